"""The bare EKF (no gate, robust loss, self-calibration, per-wall noise; uncorrected ranges)
of many runs as arrays with a leading run axis: a filter bank (estimators.core) whose predict
and update cost a few array operations for all Monte Carlo runs of a cell, so the epoch loop
(core.epoch_loop) steps every run x parameter set of a paper's table at once; a single run
is a batch of one.

Runs whose epoch grids and measurement sets differ:
- the measurements of epoch k of all runs (any kinds and anchor subsets) are padded to
  the largest count M_k: a padded row has H = 0, y = 0 and R = 1, so S = H P H^T + R is
  block-diagonal with an identity block for the padding, K is 0 on it, and neither x, P nor
  NIS = y^T S^-1 y changes;
- per run, measurement i of an epoch is a range or an RSS value, h and H by
  filters.measurement_models (range_rows, rss_rows: distances with the anchor's height offset
  dz, RSS floored at d0) on the whole padded array; R is diagonal (range sigma^2, RSS sigma_dB^2).
Predict and update are filters.kalman's (predict as one filter's, here with a leading run axis;
the update is diagonal_update, the Joseph-form update's information form for a diagonal R: its
inverses are state-sized, where the covariance form inverts the padded M_k x M_k S).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnloc.estimators import filter_options
from wsnloc.estimators.core import RunInputs
from wsnloc.filters.kalman import diagonal_update, predict
from wsnloc.filters.measurement_models import range_rows, rss_rows
from wsnloc.filters.numerics import Guards

RANGE, RSS = 0, 1


@dataclass
class Measurements:
    """Padded per-epoch measurements of several runs: arrays (runs, epochs, M), M the
    largest count of any epoch; `count` (runs, epochs) the real ones (first in each row)."""

    count: np.ndarray          # int, measurements per (run, epoch)
    kind: np.ndarray           # RANGE or RSS
    anchors: np.ndarray        # (runs, epochs, M, 2) anchor x, y (m)
    dz: np.ndarray             # anchor height - tag height (m), 0 for RSS and 2-D ranges
    p0: np.ndarray             # RSS: P0 (dBm) at d0
    exponent: np.ndarray       # RSS: path-loss exponent n
    d0: np.ndarray             # RSS: reference distance (m)
    variance: np.ndarray       # R diagonal (m^2 or dB^2); 1 where padded
    z: np.ndarray              # measured values (m or dBm); 0 where padded

    @classmethod
    def empty(cls, runs: int, epochs: int, width: int) -> "Measurements":
        shape = (runs, epochs, width)
        return cls(np.zeros(shape[:2], dtype=int), np.zeros(shape, dtype=np.int8), np.zeros(shape + (2,)),
                   np.zeros(shape), np.zeros(shape), np.zeros(shape), np.ones(shape), np.ones(shape), np.zeros(shape))

    def at(self, k: int, runs: np.ndarray) -> "Measurements":
        """Epoch k of the given runs, trimmed to their largest count."""
        width = max(int(self.count[runs, k].max()), 1)
        take = lambda a: a[runs, k, :width]     # noqa: E731
        return Measurements(self.count[runs, k], take(self.kind), take(self.anchors), take(self.dz), take(self.p0),
                            take(self.exponent), take(self.d0), take(self.variance), take(self.z))


def update(x: np.ndarray, P: np.ndarray, m: Measurements):
    """The EKF update (filters.kalman.diagonal_update) of every run with its (padded) measurements;
    returns (x, P, NIS, ok). h and the position columns of H are filters.measurement_models'
    (range_rows, rss_rows), the other columns 0; R = diag(variance). A run whose update is
    not finite (ok False) keeps its prior, NIS NaN."""
    runs, width = m.z.shape
    diff = x[:, None, :2] - m.anchors
    h, H_p = range_rows(diff, m.dz)
    is_rss = m.kind == RSS
    if is_rss.any():                          # the RSS model's rows (range-only epochs skip it)
        h_rss, H_rss = rss_rows(diff, m.p0, m.exponent, m.d0, m.dz)
        h, H_p = np.where(is_rss, h_rss, h), np.where(is_rss[..., None], H_rss, H_p)
    real = np.arange(width)[None, :] < m.count[:, None]
    H = np.zeros((runs, width, x.shape[1]))
    H[..., :2] = np.where(real[..., None], H_p, 0.0)
    y = np.where(real, m.z - h, 0.0)
    new = diagonal_update(x, P, y, H, m.variance)
    return new.x, new.P, np.where(new.ok, new.nis, np.nan), new.ok


def pack(runs: list[RunInputs], period: float) -> tuple[Measurements, np.ndarray]:
    """The epochs of every run (MeasurementSource.epoch_means: per-anchor means; ranges first,
    then RSS, each by anchor id, as in MeasurementSource.epochs and .model) in one padded
    Measurements, and the row of each run in it: cells sharing a measurement source and grid
    (e.g. a row with and without motion detection) share one row."""
    rows: dict[tuple, int] = {}
    row_of = np.array([rows.setdefault((id(run.source), id(run.times)), len(rows)) for run in runs], dtype=np.intp)
    first = np.unique(row_of, return_index=True)[1]                       # the first run of each row
    flat = [_flatten(runs[first[row]], period) for row in range(len(rows))]
    width = max([int(counts.max(initial=0)) for _, counts, _ in flat] + [1])
    out = Measurements.empty(len(rows), max([len(r.times) for r in runs] + [0]), width)
    for row, parts in enumerate(flat):
        _fill(out, row, runs[first[row]], *parts)
    return out, row_of


def _flatten(run: RunInputs, period: float) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(epoch of each measurement, count per epoch, per-measurement columns (is_rss, anchor
    x y (m), dz (m), value)) of one run's epochs, ordered by epoch, then ranges before RSS."""
    source, data = run.source, run.source.data
    parts = source.epoch_means(run.times, period)
    epoch = np.concatenate([m.epoch for m in parts])
    is_rss = np.concatenate([np.full(len(m.epoch), kind == 1) for kind, m in enumerate(parts)])
    ids = [source.anchor_ids(kind) for kind in range(2)]
    xy = np.concatenate([data.positions(ids[kind])[m.code] for kind, m in enumerate(parts)])
    dz = np.concatenate([data.height_offsets(ids[kind])[m.code] if data.three_d else np.zeros(len(m.code))
                         for kind, m in enumerate(parts)])
    value = np.concatenate([m.mean for m in parts])
    order = np.argsort(epoch, kind="stable")
    counts = np.bincount(epoch, minlength=len(run.times))
    return epoch[order], counts, (is_rss[order], xy[order], dz[order], value[order])


def _fill(out: Measurements, i: int, run: RunInputs, epoch: np.ndarray, counts: np.ndarray, columns: tuple) -> None:
    """Row i of `out`: one run's flattened epochs (_flatten)."""
    is_rss, xy, dz, value = columns
    rss = run.source.rss_params
    slot = np.arange(len(epoch)) - np.repeat(np.cumsum(counts) - counts, counts)   # index within the epoch
    out.count[i, :len(counts)] = counts
    out.kind[i, epoch, slot] = np.where(is_rss, RSS, RANGE)
    out.anchors[i, epoch, slot] = xy
    out.dz[i, epoch, slot] = dz
    out.z[i, epoch, slot] = value
    out.variance[i, epoch, slot] = run.source.range_sigma_m**2
    if is_rss.any():
        at = (i, epoch[is_rss], slot[is_rss])
        out.p0[at], out.exponent[at], out.d0[at] = rss.p0_dbm, rss.path_loss_exponent, rss.d0_m
        out.variance[at] = rss.sigma_db**2


def supports(p: dict) -> bool:
    """Whether the resolved parameters `p` are the epoch-mode EKF this module steps: the bare
    filter (no gate, robust loss, self-calibration, per-wall noise) on uncorrected ranges or RSS
    (TDOA runs as a filter bank: its noise is not diagonal), with a 2-D state and a motion model
    whose F does not depend on an input (not odometry)."""
    bare = all(p.get(k, off) == off for k, off in filter_options.OFF.items())
    return p.get("filter") == "ekf" and p.get("update") == "epoch" and bare \
        and p.get("range_calibration", "none") == "none" and p.get("measurements") != "tdoa" \
        and p.get("dimensions", 2) == 2 and p.get("motion") != "odometry"


class ArrayEKF:
    """The bare EKF of several runs as a filter bank (estimators.core): state x (runs, n),
    covariance P (runs, n, n), the runs' epochs packed (pack); guards: each run's counters
    (filters.numerics; an update that is not finite is skipped and counted)."""

    def __init__(self, runs: list[RunInputs], period: float, dim: int, bounds: list | None = None,
                 guards: list[Guards] | None = None):
        self.measurements, self.row_of = pack(runs, period)
        self.guards = guards or [Guards() for _ in runs]       # per run: updates skipped
        bounds = bounds or [None] * len(runs)
        self.bounded = np.array([b is not None for b in bounds])
        self.low = np.array([b[0] if b is not None else [-np.inf, -np.inf] for b in bounds]).reshape(-1, 2)
        self.high = np.array([b[1] if b is not None else [np.inf, np.inf] for b in bounds]).reshape(-1, 2)
        self.count = self.measurements.count[self.row_of]          # (runs, epochs)
        self.x, self.P = np.zeros((len(runs), dim)), np.zeros((len(runs), dim, dim))

    def start(self, i: int, x0: np.ndarray, P0: np.ndarray, motion) -> None:
        self.x[i], self.P[i] = x0, P0

    def track(self, i: int):
        raise NotImplementedError("the array EKF records no forward pass (the smoothers use a FilterBank)")

    def predict(self, rows: np.ndarray, F, Q, B, u: np.ndarray | None) -> None:
        """x <- F x (+ B u where u is finite), P <- F P F^T + Q for the given runs."""
        if not len(rows):
            return
        Bu = None
        if B is not None and u is not None:
            Bu = np.where(np.isfinite(u).all(axis=1)[:, None], np.nan_to_num(u) @ B.T, 0.0)
        self.x[rows], self.P[rows] = predict(self.x[rows], self.P[rows], F, Q, Bu)

    def update(self, rows: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Update the given runs with their epoch-k measurements: (used, NIS, lost = False)."""
        used = self.count[rows, k]
        nis = np.full(len(rows), np.nan)
        measured = rows[used > 0]
        if len(measured):
            self.x[measured], self.P[measured], nis[used > 0], ok = update(
                self.x[measured], self.P[measured], self.measurements.at(k, self.row_of[measured]))
            for i in measured[~ok]:
                self.guards[i].skipped += 1
            if self.bounded.any():
                self.x[measured, :2] = np.clip(self.x[measured, :2], self.low[measured], self.high[measured])
        return used, nis, np.zeros(len(rows), bool)

    def estimates(self, rows) -> np.ndarray:
        """[x, y, p_xx, p_xy, p_yy] of the given runs."""
        x, P = self.x[rows], self.P[rows]
        return np.column_stack([x[:, 0], x[:, 1], P[:, 0, 0], P[:, 0, 1], P[:, 1, 1]])
