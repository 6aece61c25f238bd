"""The results contract: reports/results.csv, one row per reported number.

Columns: experiment, table, row, column, scenario, metric, value, ci95_low, ci95_high,
band_low, band_high, runs, paper_value (empty where not applicable). The report and outside
tooling read this file, never internal objects.

ci95_low / ci95_high: the 95% interval of a mean over Monte Carlo runs (metrics.stats.mean_interval,
inside the metric's range, empty with fewer than MIN_INTERVAL_RUNS runs). band_low / band_high:
the 95% band one realisation falls in, not an interval of the mean: for a test statistic (ANEES,
ANIS) its chi-square acceptance band (metrics.consistency); for a Monte Carlo row whose paper value
is one published run (a single real experiment), the 2.5 and 97.5 percentiles of our per-run values
(run_band). A paper value is compared with the band when the row has one, else with the mean's
interval (a published mean, e.g. paper B's average over 20 simulations): verdicts.paper_value_inside.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc.metrics.stats import MIN_INTERVAL_RUNS, mean_interval

COLUMNS = ["experiment", "table", "row", "column", "scenario", "metric",
           "value", "ci95_low", "ci95_high", "band_low", "band_high", "runs", "paper_value"]
KEY = COLUMNS[:6]      # the labels that name a number: no two rows of a file share them

# signed per-run values (and difference_*); a range scale fitted by regression (diag_range_scale) can come
# out of any sign on a degenerate run, so its interval is not forced positive
SIGNED_METRICS = ("P0_dBm", "range_error_m", "rmse_gain_m", "range_offset_m", "verdict", "diag_range_scale_1",
                  "speed_bias_mps")


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
                  scenario: str, metric: str, paper_value: float | None = None,
                  paper_is_mean: bool = False) -> dict:
    """A results row whose value is the mean over runs with its 95% interval (mean_interval
    on the metric's domain, metric_domain). With a paper value from one published run (not
    `paper_is_mean`), band_low / band_high hold the per-run band (run_band) it is compared with."""
    values = [v for v in per_run_values if pd.notna(v)]
    try:
        mean, low, high = mean_interval(values, metric_domain(metric))
    except ValueError as exc:
        raise ValueError(f"results row {experiment}/{table}/{row}/{column} ({metric}): {exc}") from None
    band = run_band(values) if paper_value is not None and not paper_is_mean else (None, None)
    return {"experiment": experiment, "table": table, "row": row, "column": column,
            "scenario": scenario, "metric": metric, "value": mean, "ci95_low": low,
            "ci95_high": high, "band_low": band[0], "band_high": band[1], "runs": len(values),
            "paper_value": paper_value}


RUN_BAND_PERCENTILES = (2.5, 97.5)


def run_band(values, min_runs: int = MIN_INTERVAL_RUNS) -> tuple[float | None, float | None]:
    """The interval one run falls in with 95% probability, estimated by the 2.5 and 97.5
    percentiles (numpy's linear interpolation) of the per-run values; (None, None) with fewer than
    `min_runs` finite values. A single published run is compared with this, not with the interval
    of our mean (which shrinks as 1 / sqrt(runs) and would refuse a typical run)."""
    values = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    if len(values) < min_runs:
        return None, None
    low, high = np.percentile(values, RUN_BAND_PERCENTILES)
    return float(low), float(high)


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
