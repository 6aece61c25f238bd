"""Group asynchronous measurements into estimation periods ("epochs").

Epoch k ends at t_k = t_first + k * period and collects the measurements with
t in (t_k - period, t_k]. An estimator run in real time produces its estimate at t_k,
so errors are scored against the truth at t_k.

All estimators of one run share one grid (`run_grid`): it starts at the run's first
usable measurement, whatever the estimator's anchor subset, so that the outputs of
different estimators and subsets fall at the same times and can be compared pairwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd



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
    """Per epoch ending at `times`: (anchor ids in sorted order, mean of `value` per anchor)."""
    out = [(np.array([], dtype=object), np.array([]))] * len(times)      # one shared empty pair
    epoch = _assign(frame["t"].to_numpy(float), times, period)
    inside = epoch >= 0
    if not inside.any():
        return out
    epoch, values = epoch[inside], frame[value].to_numpy(float)[inside]
    ids, code = _sorted_codes(frame["anchor_id"])
    code = code[inside]
    order = np.lexsort((code, epoch))                   # by epoch, then anchor id
    epoch, code, values = epoch[order], code[order], values[order]
    first = np.flatnonzero(np.r_[True, (epoch[1:] != epoch[:-1]) | (code[1:] != code[:-1])])   # one per (epoch, anchor)
    means = np.add.reduceat(values, first) / np.diff(np.r_[first, len(values)])
    group_epoch, group_ids = epoch[first], ids[code[first]].astype(object)
    starts = np.flatnonzero(np.r_[True, group_epoch[1:] != group_epoch[:-1]])      # first group of each epoch
    for k, a, b in zip(group_epoch[starts], starts, np.r_[starts[1:], len(group_epoch)]):
        out[k] = (group_ids[a:b], means[a:b])
    return out


def _sorted_codes(anchor_ids: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    """np.unique(anchor_ids as str, return_inverse=True), by hashing (pd.factorize) and sorting
    only the distinct ids: (ids in sorted order, index of each row's id in them)."""
    code, distinct = pd.factorize(anchor_ids, use_na_sentinel=False)
    names = np.asarray(distinct, dtype=object).astype(str)
    order = np.argsort(names, kind="stable")
    rank = np.empty(len(order), dtype=np.intp)
    rank[order] = np.arange(len(order))
    return names[order], rank[code]


def grid_over(stamps: np.ndarray, period: float) -> np.ndarray:
    """Epoch end times covering the measurement times `stamps` (s): the first epoch ends
    one period after the first measurement (minus 1 ns, so it holds that measurement)."""
    if len(stamps) == 0:
        return np.array([])
    start = float(np.min(stamps)) - 1e-9
    return epoch_times(start, float(np.max(stamps)) + period, period)


def build_epochs(ranges: pd.DataFrame, rss: pd.DataFrame, period: float,
                 times: np.ndarray | None = None) -> list[Epoch]:
    """Epochs ending at `times` (default: the grid over all the given measurements).

    Several ranges to one anchor within an epoch are averaged (m); RSS samples are
    averaged per anchor in dB (the mean of the log-normal samples, which is the ML
    estimate of the local mean power under the shadowing model).
    """
    if times is None:
        times = grid_over(np.concatenate([ranges["t"].to_numpy(float), rss["t"].to_numpy(float)]), period)
    grouped_ranges = _per_anchor_mean(ranges, "range_m", times, period)
    grouped_rss = _per_anchor_mean(rss, "rss_dbm", times, period)
    return [Epoch(float(t), gr[0], gr[1], gs[0], gs[1]) for t, gr, gs in zip(times, grouped_ranges, grouped_rss)]
