"""Group asynchronous measurements into estimation periods ("epochs").

Epoch k ends at t_k = t_first + k * period and collects the measurements with
t in (t_k - period, t_k]. An estimator run in real time produces its estimate at t_k,
so errors are scored against the truth at t_k.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc.metrics.ranging import truth_at


@dataclass
class Epoch:
    t: float
    range_ids: np.ndarray      # UWB (or other ranging) anchor ids
    ranges: np.ndarray         # m
    rss_ids: np.ndarray        # RSS anchor ids
    rss: np.ndarray            # dBm, mean over the epoch per anchor


def epoch_times(start: float, end: float, period: float) -> np.ndarray:
    return start + period * np.arange(1, int(np.floor((end - start) / period)) + 1)


def _assign(t: np.ndarray, times: np.ndarray, period: float) -> np.ndarray:
    """Index of the epoch (t_k - period, t_k] each time falls in, -1 outside all epochs."""
    index = np.searchsorted(times, t, side="left")
    valid = (index < len(times)) & (t > times[np.minimum(index, len(times) - 1)] - period)
    return np.where(valid, index, -1)


def _per_anchor_mean(frame: pd.DataFrame, value: str, times, period) -> list[tuple[np.ndarray, np.ndarray]]:
    out = [(np.array([], dtype=object), np.array([])) for _ in times]
    if len(frame) == 0:
        return out
    frame = frame.assign(epoch=_assign(frame["t"].to_numpy(), times, period))
    frame = frame[frame["epoch"] >= 0]
    if len(frame) == 0:
        return out
    means = frame.groupby(["epoch", "anchor_id"], sort=True)[value].mean()
    epochs = means.index.get_level_values(0).to_numpy()
    ids = means.index.get_level_values(1).to_numpy(dtype=object)
    values = means.to_numpy(dtype=float)
    starts = np.flatnonzero(np.r_[True, epochs[1:] != epochs[:-1]])      # first row of each epoch
    for k, a, b in zip(epochs[starts], starts, np.r_[starts[1:], len(epochs)]):
        out[k] = (ids[a:b], values[a:b])
    return out


def build_epochs(ranges: pd.DataFrame, rss: pd.DataFrame, period: float,
                 start: float | None = None, end: float | None = None) -> list[Epoch]:
    """Epochs over [start, end] (defaults: the span of all measurements).

    Several ranges to one anchor within an epoch are averaged (m); RSS samples are
    averaged per anchor in dB (the mean of the log-normal samples, which is the ML
    estimate of the local mean power under the shadowing model).
    """
    stamps = np.concatenate([ranges["t"].to_numpy(float), rss["t"].to_numpy(float)])
    if len(stamps) == 0:
        return []
    start = float(stamps.min()) - 1e-9 if start is None else start
    end = float(stamps.max()) + period if end is None else end
    times = epoch_times(start, end, period)
    grouped_ranges = _per_anchor_mean(ranges, "range_m", times, period)
    grouped_rss = _per_anchor_mean(rss, "rss_dbm", times, period)
    return [Epoch(float(t), gr[0], gr[1], gs[0], gs[1]) for t, gr, gs in zip(times, grouped_ranges, grouped_rss)]


def score(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Add true_x, true_y (truth at the estimate time) and error_m = ||estimate - truth||."""
    position = truth_at(truth, estimates["t"].to_numpy(float))
    out = estimates.copy()
    out["true_x"], out["true_y"] = position[:, 0], position[:, 1]
    out["error_m"] = np.hypot(out["x"] - out["true_x"], out["y"] - out["true_y"])
    return out
