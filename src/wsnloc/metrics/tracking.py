"""Scoring estimates against ground truth: errors, availability and per-run metrics.

Applied the same way to every estimator, study and paper.
- error at an estimate time t: ||p_hat(t) - p(t)||, with p(t) the truth interpolated at t;
- availability: the share of the truth time span [T0, T1] covered by estimates, each
  finite estimate at t covering the output period before it, (t - T, t]; T is the
  estimator's output period (the median spacing of its output times);
- per-run metrics: RMSE, mean, median, p75 (EvAAL's third quartile), p90, p95, max (m),
  number of estimates n and availability; per cell also rmse_moving, the RMSE over the
  estimates at which the target moves (true speed at least STATIC_SPEED_MPS, moving_mask):
  claims about speed compare moving epochs only, so the rests' share does not decide them.
- 3-D: where the truth has a height z and the estimates a z (a 3-D state), also
  error_3d_m = ||(x, y, z) estimate - truth|| and its RMSE rmse_3d (m); errors are
  horizontal (2-D) otherwise.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from wsnloc.metrics.ranging import truth_at
from wsnloc.metrics.stats import ERROR_STATS, error_summary

RUN_METRICS = ERROR_STATS + ("availability",)
STATIC_SPEED_MPS = 0.01      # the carts' slowest motion is 0.1 m/s; 1 cm/s is standing still


def true_speeds(t: np.ndarray, true_x: np.ndarray, true_y: np.ndarray) -> np.ndarray:
    """True speed (m/s) at each estimate of one cell: ||p(t_k) - p(t_{k-1})|| / (t_k - t_{k-1})
    over the estimates in time order (the first takes the second's; NaN with fewer than 2 and
    where t_k = t_{k-1})."""
    order = np.argsort(t, kind="stable")
    speed = np.full(len(t), np.nan)
    if len(t) < 2:
        return speed
    ts, xs, ys = t[order], true_x[order], true_y[order]
    dt = np.diff(ts)
    with np.errstate(invalid="ignore", divide="ignore"):
        step = np.where(dt > 0, np.hypot(np.diff(xs), np.diff(ys)) / np.where(dt > 0, dt, 1.0), np.nan)
    speed[order] = np.concatenate([step[:1], step])
    return speed


def moving_mask(t: np.ndarray, true_x: np.ndarray, true_y: np.ndarray) -> np.ndarray:
    """True where the target moves at the estimate (true_speeds >= STATIC_SPEED_MPS)."""
    speed = true_speeds(t, true_x, true_y)
    return np.isfinite(speed) & (speed >= STATIC_SPEED_MPS)


def score(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Add true_x, true_y (truth at the estimate time) and error_m = ||estimate - truth|| (m):
    a new frame (index and attrs of `estimates`) built at once from its columns and these
    three (replacing any of those names in place), not a copy assigned column by column."""
    position = truth_at(truth, estimates["t"].to_numpy(float))
    error = np.hypot(estimates["x"].to_numpy(float) - position[:, 0], estimates["y"].to_numpy(float) - position[:, 1])
    spatial = {}
    if "z" in estimates and "z" in truth and np.isfinite(truth["z"].to_numpy(float)).any():
        given = np.isfinite(truth["z"].to_numpy(float))           # rows with a height (z may be left empty)
        true_z = np.interp(estimates["t"].to_numpy(float), truth["t"][given], truth["z"][given],
                           left=np.nan, right=np.nan)
        spatial = {"true_z": true_z, "error_3d_m": np.hypot(error, estimates["z"].to_numpy(float) - true_z)}
    out = pd.DataFrame({**{name: estimates[name].array for name in estimates.columns},
                        "true_x": position[:, 0], "true_y": position[:, 1], "error_m": error, **spatial},
                       index=estimates.index)
    out.attrs = copy.deepcopy(estimates.attrs)
    return out


def output_period(t: np.ndarray) -> float:
    """The estimator's output period (s): median spacing of its output times (NaN if < 2)."""
    steps = np.diff(np.unique(t))
    return float(np.median(steps)) if len(steps) else float("nan")


def truth_span(truth: pd.DataFrame) -> tuple[float, float] | None:
    """[T0, T1] (s): the first and last truth times (NaN ignored); None with fewer than two truth rows."""
    if len(truth) < 2:
        return None
    t = truth["t"].to_numpy(float)
    return float(np.nanmin(t)), float(np.nanmax(t))


def availability(estimates: pd.DataFrame, truth: pd.DataFrame, period: float | None = None) -> float:
    """Share of [T0, T1] covered by the union of (t_i - T, t_i] over the finite estimates."""
    finite = np.isfinite(estimates["x"].to_numpy(float)) & np.isfinite(estimates["y"].to_numpy(float))
    return covered_share(estimates["t"].to_numpy(float), finite, truth_span(truth), period)


def covered_share(t: np.ndarray, finite: np.ndarray, span: tuple[float, float] | None,
                  period: float | None = None) -> float:
    """Availability of estimates at times t (s), `finite` marking those with a position.

    With T the period (s; output_period(t) if None, 0 if not finite), e_i the finite
    estimates' times sorted and clipped to span = [T0, T1] and s_i = clip(e_i - T, T0, T1):
      A = sum_i max(0, e_i - max(s_i, r_i)) / (T1 - T0),  r_i = max(T0, e_{i-1}),
    the length of the union of the intervals (s_i, e_i] over the span's length. The running
    reach r_i is the previous end because the e_i are sorted; empty intervals (e_i <= s_i,
    NaN times) cover nothing and are dropped first, so they set no reach.
    NaN if span is None (truth too short), 0 without finite estimates or if T1 <= T0.
    """
    if span is None:
        return float("nan")
    t0, t1 = span
    period = output_period(t) if period is None else period
    if not finite.any() or t1 <= t0:
        return 0.0
    if not np.isfinite(period):
        period = 0.0
    ends = np.clip(np.sort(t[finite]), t0, t1)
    starts = np.clip(ends - period, t0, t1)
    nonempty = ends > starts
    ends, starts = ends[nonempty], starts[nonempty]
    reach = np.concatenate(([t0], ends[:-1]))
    return float(np.sum(np.maximum(ends - np.maximum(starts, reach), 0.0))) / (t1 - t0)


def run_metrics(scored: pd.DataFrame, truth: pd.DataFrame, period: float | None = None) -> dict[str, float]:
    """The per-run metrics (RUN_METRICS) of one run's scored estimates, and rmse_3d (m) where
    they have 3-D errors (score)."""
    stats = error_summary(scored["error_m"]) if len(scored) else error_summary([])
    spatial = {"rmse_3d": error_summary(scored["error_3d_m"])["rmse"]} if "error_3d_m" in scored else {}
    return {**stats, "availability": availability(scored, truth, period), **spatial}


def cell_metrics(scored: pd.DataFrame, keys: list[str], truth: pd.DataFrame) -> pd.DataFrame:
    """RUN_METRICS of each cell (group of `keys`, in order of first appearance; rows with a
    missing key are left out) of one run's scored estimates. The cells are index arrays into
    the columns (no sub-frame per cell); the truth span is read once."""
    span, (names, cells) = truth_span(truth), cell_rows(scored, keys)
    t, x, y, error, true_x, true_y = (scored[c].to_numpy(float) for c in ("t", "x", "y", "error_m", "true_x", "true_y"))
    finite = np.isfinite(x) & np.isfinite(y)
    records = [{**dict(zip(keys, name)), **error_summary(error[rows]),
                "availability": covered_share(t[rows], finite[rows], span),
                "rmse_moving": error_summary(error[rows][moving_mask(t[rows], true_x[rows], true_y[rows])])["rmse"]}
               for name, rows in zip(names, cells)]
    return pd.DataFrame(records, columns=keys + list(RUN_METRICS) + ["rmse_moving"])


def cell_rows(frame: pd.DataFrame, keys: list[str]) -> tuple[list[tuple], list[np.ndarray]]:
    """(key values, row positions (ascending)) of each group of `keys`, in groupby(keys,
    sort=False) order (first appearance); rows with a missing key are in none. Each key
    column is factorized once (code -1: missing); a row's group is its codes combined,
    c = (...(c_1 n_2 + c_2) n_3 + ...) with n_i the distinct values of key i."""
    codes, uniques = zip(*(pd.factorize(frame[key]) for key in keys))
    combined = np.zeros(len(frame), dtype=np.int64)
    for code, distinct in zip(codes, uniques):
        combined = combined * len(distinct) + code
    valid = np.flatnonzero(np.all([code >= 0 for code in codes], axis=0))
    _, first, inverse = np.unique(combined[valid], return_index=True, return_inverse=True)
    appearance = np.argsort(first)                        # groups in order of their first row
    group = np.empty(len(first), dtype=np.intp)
    group[appearance] = np.arange(len(first))
    ids = group[inverse.reshape(-1)]
    order = valid[np.argsort(ids, kind="stable")]
    ends = np.cumsum(np.bincount(ids, minlength=len(first)))
    rows = np.split(order, ends[:-1]) if len(first) else []
    names = [tuple(distinct[code[r[0]]] for code, distinct in zip(codes, uniques)) for r in rows]
    return names, rows
