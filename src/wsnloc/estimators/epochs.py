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


@dataclass
class AnchorMeans:
    """Per (epoch, anchor) means of one kind of measurement, ordered by epoch, then anchor:
    `epoch` (index into the epoch end times), `code` (index of the anchor id in the sorted
    distinct ids it was coded with, sorted_codes) and `mean` (m or dB)."""

    epoch: np.ndarray
    code: np.ndarray
    mean: np.ndarray

    def select(self, keep: np.ndarray) -> "AnchorMeans":
        """The (epoch, anchor) means where `keep` (bool, per row) holds."""
        return AnchorMeans(self.epoch[keep], self.code[keep], self.mean[keep])


def anchor_means(t: np.ndarray, code: np.ndarray, values: np.ndarray, times: np.ndarray,
                 period: float) -> AnchorMeans:
    """Per epoch (t_k - period, t_k] ending at `times` and per anchor code: the mean of the
    `values` at times t (s) in it, sum(values) / count in the order given (samples outside
    every epoch are dropped)."""
    epoch = _assign(t, times, period)
    inside = epoch >= 0
    epoch, code, values = epoch[inside], code[inside], values[inside]
    if len(epoch) == 0:
        return AnchorMeans(epoch, code, values)
    order = np.lexsort((code, epoch))                   # by epoch, then anchor id
    epoch, code, values = epoch[order], code[order], values[order]
    first = np.flatnonzero(np.r_[True, (epoch[1:] != epoch[:-1]) | (code[1:] != code[:-1])])   # one per (epoch, anchor)
    means = np.add.reduceat(values, first) / np.diff(np.r_[first, len(values)])
    return AnchorMeans(epoch[first], code[first], means)


def per_epoch(means: AnchorMeans, ids: np.ndarray, n_epochs: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per epoch of n_epochs: (anchor ids (object, ids[code]), means), empty where none."""
    out = [(np.array([], dtype=object), np.array([]))] * n_epochs      # one shared empty pair
    if len(means.epoch) == 0:
        return out
    group_ids = ids[means.code]
    starts = np.flatnonzero(np.r_[True, means.epoch[1:] != means.epoch[:-1]])      # first group of each epoch
    for k, a, b in zip(means.epoch[starts], starts, np.r_[starts[1:], len(means.epoch)]):
        out[k] = (group_ids[a:b], means.mean[a:b])
    return out


def _per_anchor_mean(frame: pd.DataFrame, value: str, times, period) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per epoch ending at `times`: (anchor ids in sorted order, mean of `value` per anchor)."""
    ids, code = sorted_codes(frame["anchor_id"])
    means = anchor_means(frame["t"].to_numpy(float), code, frame[value].to_numpy(float), times, period)
    return per_epoch(means, ids.astype(object), len(times))


def sorted_codes(anchor_ids: pd.Series) -> tuple[np.ndarray, np.ndarray]:
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
    one period after the first measurement (minus 1 ns, so it holds that measurement; at least
    one float64 step below it: at Unix times, t ~ 1.7e9 s, 1 ns is below the resolution and the
    first measurement fell outside the first epoch)."""
    if len(stamps) == 0:
        return np.array([])
    first = float(np.min(stamps))
    start = min(first - 1e-9, float(np.nextafter(first, -np.inf)))
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
