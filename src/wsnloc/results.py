"""The results contract: reports/results.csv, one row per reported number.

Columns: experiment, table, row, column, scenario, metric, value, ci95_low, ci95_high,
band_low, band_high, runs, paper_value (empty where not applicable). The report and outside
tooling read this file, never internal objects.

ci95_low / ci95_high: the 95% interval of a mean over Monte Carlo runs (metrics.stats.mean_interval,
inside the metric's range, empty with fewer than MIN_INTERVAL_RUNS runs). band_low / band_high:
the 95% acceptance band of a test statistic (ANEES, ANIS: chi-square, metrics.consistency), not
an interval of the value.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from wsnloc.metrics.stats import mean_interval

COLUMNS = ["experiment", "table", "row", "column", "scenario", "metric",
           "value", "ci95_low", "ci95_high", "band_low", "band_high", "runs", "paper_value"]
KEY = COLUMNS[:6]      # the labels that name a number: no two rows of a file share them

# signed per-run values (and difference_*); a range scale fitted by regression (diag_range_scale) can come
# out of any sign on a degenerate run, so its interval is not forced positive
SIGNED_METRICS = ("P0_dBm", "range_error_m", "rmse_gain_m", "range_offset_m", "verdict", "diag_range_scale_1")


def metric_domain(metric: str) -> str:
    """The range of a metric's per-run values, for mean_interval: 'share' (in [0, 1]: names
    ending in share, availability), 'real' (signed: SIGNED_METRICS, differences), else
    'nonnegative' (errors, bounds, ratios, counts, times)."""
    if metric.endswith("share") or metric == "availability":
        return "share"
    if metric in SIGNED_METRICS or metric.startswith("difference"):
        return "real"
    return "nonnegative"


def row_over_runs(per_run_values, *, experiment: str, table: str, row: str, column: str,
                  scenario: str, metric: str, paper_value: float | None = None) -> dict:
    """A results row whose value is the mean over runs with its 95% interval (mean_interval
    on the metric's domain, metric_domain)."""
    values = [v for v in per_run_values if pd.notna(v)]
    try:
        mean, low, high = mean_interval(values, metric_domain(metric))
    except ValueError as exc:
        raise ValueError(f"results row {experiment}/{table}/{row}/{column} ({metric}): {exc}") from None
    return {"experiment": experiment, "table": table, "row": row, "column": column,
            "scenario": scenario, "metric": metric, "value": mean, "ci95_low": low,
            "ci95_high": high, "band_low": None, "band_high": None, "runs": len(values),
            "paper_value": paper_value}


def single_row(value, *, experiment: str, table: str, row: str, column: str, scenario: str,
               metric: str, paper_value: float | None = None) -> dict:
    """A results row for a number that is not a Monte Carlo mean (a count, a measured time)."""
    return {"experiment": experiment, "table": table, "row": row, "column": column,
            "scenario": scenario, "metric": metric, "value": value, "ci95_low": None,
            "ci95_high": None, "band_low": None, "band_high": None, "runs": None, "paper_value": paper_value}


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
