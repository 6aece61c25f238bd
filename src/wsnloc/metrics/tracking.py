"""Scoring estimates against ground truth: errors, availability and per-run metrics.

Applied the same way to every estimator, study and paper.
- error at an estimate time t: ||p_hat(t) - p(t)||, with p(t) the truth interpolated at t;
- availability: the share of the truth time span [T0, T1] covered by estimates, each
  finite estimate at t covering the output period before it, (t - T, t]; T is the
  estimator's output period (the median spacing of its output times);
- per-run metrics: RMSE, mean, median, p75 (EvAAL's third quartile), p90, p95, max (m),
  number of estimates n and availability.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.metrics.ranging import truth_at
from wsnloc.metrics.stats import ERROR_STATS, error_summary

RUN_METRICS = ERROR_STATS + ("availability",)


def score(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Add true_x, true_y (truth at the estimate time) and error_m = ||estimate - truth||."""
    position = truth_at(truth, estimates["t"].to_numpy(float))
    out = estimates.copy()
    out["true_x"], out["true_y"] = position[:, 0], position[:, 1]
    out["error_m"] = np.hypot(out["x"] - out["true_x"], out["y"] - out["true_y"])
    return out


def output_period(t: np.ndarray) -> float:
    """The estimator's output period (s): median spacing of its output times (NaN if < 2)."""
    steps = np.diff(np.unique(t))
    return float(np.median(steps)) if len(steps) else float("nan")


def availability(estimates: pd.DataFrame, truth: pd.DataFrame, period: float | None = None) -> float:
    """Share of [T0, T1] covered by the union of (t_i - T, t_i] over the finite estimates."""
    if len(truth) < 2:
        return float("nan")
    t0, t1 = float(truth["t"].min()), float(truth["t"].max())
    finite = estimates[np.isfinite(estimates["x"]) & np.isfinite(estimates["y"])]["t"].to_numpy(float)
    period = output_period(estimates["t"].to_numpy(float)) if period is None else period
    if len(finite) == 0 or t1 <= t0:
        return 0.0
    if not np.isfinite(period):
        period = 0.0
    ends = np.clip(np.sort(finite), t0, t1)
    starts = np.clip(ends - period, t0, t1)
    covered, reach = 0.0, t0
    for a, b in zip(starts, ends):
        a = max(a, reach)
        if b > a:
            covered += b - a
            reach = b
    return covered / (t1 - t0)


def run_metrics(scored: pd.DataFrame, truth: pd.DataFrame, period: float | None = None) -> dict[str, float]:
    """The per-run metrics (RUN_METRICS) of one run's scored estimates."""
    stats = error_summary(scored["error_m"]) if len(scored) else error_summary([])
    return {**stats, "availability": availability(scored, truth, period)}


def cell_metrics(scored: pd.DataFrame, keys: list[str], truth: pd.DataFrame) -> pd.DataFrame:
    """RUN_METRICS of each cell (group of `keys`) of one run's scored estimates."""
    rows = [{**dict(zip(keys, key if isinstance(key, tuple) else (key,))), **run_metrics(group, truth)}
            for key, group in scored.groupby(keys, sort=False)]
    return pd.DataFrame(rows, columns=keys + list(RUN_METRICS))
