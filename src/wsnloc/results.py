"""The results contract: reports/results.csv, one row per reported number.

Columns: experiment, table, row, column, scenario, metric, value, ci95_low, ci95_high,
runs, paper_value (empty where not applicable). The report and outside tooling read this
file, never internal objects.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from wsnloc.metrics.stats import mean_ci95

COLUMNS = ["experiment", "table", "row", "column", "scenario", "metric",
           "value", "ci95_low", "ci95_high", "runs", "paper_value"]
KEY = COLUMNS[:6]      # the labels that name a number: no two rows of a file share them


def row_over_runs(per_run_values, *, experiment: str, table: str, row: str, column: str,
                  scenario: str, metric: str, paper_value: float | None = None) -> dict:
    """A results row whose value is the mean over runs with its 95% interval."""
    values = [v for v in per_run_values if pd.notna(v)]
    mean, low, high = mean_ci95(values)
    return {"experiment": experiment, "table": table, "row": row, "column": column,
            "scenario": scenario, "metric": metric, "value": mean, "ci95_low": low,
            "ci95_high": high, "runs": len(values), "paper_value": paper_value}


def single_row(value, *, experiment: str, table: str, row: str, column: str, scenario: str,
               metric: str, paper_value: float | None = None) -> dict:
    """A results row for a number that is not a Monte Carlo mean (a count, a measured time)."""
    return {"experiment": experiment, "table": table, "row": row, "column": column,
            "scenario": scenario, "metric": metric, "value": value, "ci95_low": None,
            "ci95_high": None, "runs": None, "paper_value": paper_value}


def frame(rows: list[dict]) -> pd.DataFrame:
    out = pd.DataFrame(rows, columns=COLUMNS)
    return out.astype({"runs": "Int64"})


def write(rows_or_frame, path: str | Path) -> None:
    """Write the rows; raises ValueError naming the file when two rows share their labels
    (KEY), since a reader could not tell which number is which."""
    data = rows_or_frame if isinstance(rows_or_frame, pd.DataFrame) else frame(rows_or_frame)
    repeated = data[data.duplicated(KEY, keep=False)]
    if len(repeated):
        raise ValueError(f"{path}: {len(repeated)} rows share their labels ({', '.join(KEY)}), e.g. "
                         f"{repeated[KEY].iloc[0].to_dict()}")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    data.to_csv(path, index=False, float_format="%.6g")


def read(path: str | Path) -> pd.DataFrame:
    data = pd.read_csv(path, dtype={"experiment": str, "table": str, "row": str, "column": str,
                                    "scenario": str, "metric": str})
    missing = [c for c in COLUMNS if c not in data.columns]
    if missing:
        raise ValueError(f"{path}: not a results file, missing columns {missing}")
    return data[COLUMNS]
