"""The epoch-mode EKF (registry `ekf` and its presets with `update: epoch`) and the KF over
fixes (`kf_tracker`) stepped on many runs at once: every array carries a leading run axis,
so one predict and one update per epoch cost a few array operations for all Monte Carlo
runs of a cell. Entry points: `run_many` (registry.run over the runs of a cell) and
`run_cells` (registry.run over (run, parameter set) cells, e.g. every run x row of a paper's
table); both also step the KF over fixes (`kf_tracker`) of many cells together.

Same filter as `bayes.run_filter` in epoch mode (same initiator, coasting limit, motion
detection and PVA input; estimates equal to round-off), for runs whose epoch grids and
measurement sets differ:
- run r's k-th epoch is processed at step k; runs with fewer epochs are masked after
  their end;
- the measurements of epoch k of all runs (any kinds and anchor subsets) are padded to
  the largest count M_k: a padded row has H = 0, y = 0 and R = 1, so it adds nothing to
  H^T R^-1 H, H^T R^-1 y or y^T R^-1 y and changes neither x, P nor NIS = y^T S^-1 y;
- per run, measurement i of an epoch is a range (h = sqrt(d^2 + dz^2),
  H = [(p - a) / h, 0...]) or an RSS value (h = P0 - 10 n log10(d / d0),
  H = [-10 n / ln10 (p - a) / d^2, 0...]) with d = max(||p - a||, 1 mm), as in
  filters.measurement_models; R is diagonal (range sigma^2, RSS sigma_dB^2).
Predict x <- F x + B u, P <- F P F^T + Q; Joseph-form update (filters.kalman), computed in
2 x 2 algebra as H sees the position only (position_update), so its cost hardly grows with M_k.
Only the initiator's multilateration runs per run (once per track start).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc.estimators import bayes, filter_options, fixes, range_calibration, registry, trackers
from wsnloc.estimators.measurements import MeasurementSource
from wsnloc.estimators.run_data import RunData
from wsnloc.filters.measurement_models import MIN_DISTANCE

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


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray, Bu: np.ndarray | None = None):
    """x <- F x (+ B u), P <- F P F^T + Q for x (runs, n), P (runs, n, n); Bu (runs, n)."""
    x = x @ F.T
    if Bu is not None:
        x = x + Bu
    return x, F @ P @ F.T + Q


def update(x: np.ndarray, P: np.ndarray, m: Measurements):
    """Joseph-form EKF update of every run with its (padded) measurements; returns (x, P, NIS).
    Only the position columns of H are non-zero: position_update."""
    width = m.z.shape[1]
    diff = x[:, None, :2] - m.anchors
    d = np.maximum(np.hypot(diff[..., 0], diff[..., 1]), MIN_DISTANCE)
    slant = np.sqrt(d**2 + m.dz**2)
    h, gain = slant, 1.0 / np.maximum(slant, MIN_DISTANCE)
    is_rss = m.kind == RSS
    if is_rss.any():                          # the RSS model's rows (range-only epochs skip it)
        h = np.where(is_rss, m.p0 - 10.0 * m.exponent * np.log10(d / m.d0), h)
        gain = np.where(is_rss, -10.0 * m.exponent / np.log(10.0) / d**2, gain)
    real = np.arange(width)[None, :] < m.count[:, None]
    H = np.where(real[..., None], diff * gain[..., None], 0.0)
    y = np.where(real, m.z - h, 0.0)
    return position_update(x, P, y, H, 1.0 / m.variance)


def position_update(x: np.ndarray, P: np.ndarray, y: np.ndarray, H: np.ndarray, r_inv: np.ndarray):
    """joseph_update with H = [H_p, 0] (H_p (runs, m, 2): the measurements see the position
    only) and R = diag(1 / r_inv) (r_inv (runs, m)), in 2 x 2 algebra whatever m:
    with C = P[:, :2], A = H_p^T R^-1 H_p, b = H_p^T R^-1 y and G = (I + A P_pp)^-1 the
    push-through identity H_p^T S^-1 = G H_p^T R^-1 gives K = C G H_p^T R^-1, so
    x <- x + C G b, K H = [C G A, 0], K R K^T = C G A G^T C^T,
    P <- (I - K H) P (I - K H)^T + K R K^T, and S^-1 y = R^-1 (y - H_p P_pp G b), so
    NIS = sum_i y_i (y - H_p dp)_i / R_ii with dp = P_pp G b the position correction."""
    weighted = np.swapaxes(H * r_inv[..., None], 1, 2)           # H_p^T R^-1 (runs, 2, m)
    A, b = weighted @ H, (weighted @ y[..., None])[..., 0]
    CG = P[:, :, :2] @ np.linalg.inv(np.eye(2) + A @ P[:, :2, :2])
    correction = (CG @ b[..., None])[..., 0]
    KH = np.zeros_like(P)
    KH[:, :, :2] = CG @ A
    joseph = np.eye(x.shape[1]) - KH
    P = joseph @ P @ np.swapaxes(joseph, 1, 2) + KH[:, :, :2] @ np.swapaxes(CG, 1, 2)
    residual = y - (H @ correction[:, :2, None])[..., 0]
    return x + correction, P, np.sum(y * residual * r_inv, axis=1)


def joseph_update(x: np.ndarray, P: np.ndarray, y: np.ndarray, H: np.ndarray, R: np.ndarray):
    """Kalman update of every run with innovation y (runs, m), H (runs or 1, m, n), R (runs or 1, m, m):
    S = H P H^T + R, K = P H^T S^-1, x <- x + K y, P <- (I - K H) P (I - K H)^T + K R K^T;
    returns (x, P, NIS = y^T S^-1 y)."""
    PHt = P @ np.swapaxes(H, -1, -2)
    S_inv = np.linalg.inv(H @ PHt + R)
    K = PHt @ S_inv
    x = x + (K @ y[..., None])[..., 0]
    joseph = np.eye(x.shape[1]) - K @ H
    P = joseph @ P @ np.swapaxes(joseph, 1, 2) + K @ R @ np.swapaxes(K, 1, 2)
    nis = (y[:, None, :] @ S_inv @ y[..., None])[:, 0, 0]
    return x, P, nis


@dataclass
class _Run:
    """What the epoch loop of one run reads: its grid, measurement source, static epochs and
    PVA inputs (built as bayes.run_filter builds them)."""

    times: np.ndarray
    source: MeasurementSource
    static: np.ndarray
    inputs: np.ndarray | None

    @classmethod
    def of(cls, data: RunData, p: dict, motion) -> "_Run":
        source, times, static, inputs = bayes.filter_inputs(data, p, motion)
        return cls(times, source, static, inputs)


def pack(runs: list[_Run], period: float) -> tuple[Measurements, np.ndarray]:
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


def _flatten(run: _Run, period: float) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(epoch of each measurement, count per epoch, per-measurement columns (is_rss, anchor
    x y (m), dz (m), value)) of one run's epochs, ordered by epoch, then ranges before RSS."""
    source, data = run.source, run.source.data
    parts = source.epoch_means(run.times, period)
    epoch = np.concatenate([m.epoch for m in parts])
    is_rss = np.concatenate([np.full(len(m.epoch), kind == 1) for kind, m in enumerate(parts)])
    ids = [source.anchor_ids(kind) for kind in range(2)]
    xy = np.concatenate([data.positions(ids[kind])[m.code] for kind, m in enumerate(parts)])
    dz = np.concatenate([data.height_offsets(ids[0])[parts[0].code] if data.three_d else np.zeros(len(parts[0].code)),
                         np.zeros(len(parts[1].code))])
    value = np.concatenate([m.mean for m in parts])
    order = np.argsort(epoch, kind="stable")
    counts = np.bincount(epoch, minlength=len(run.times))
    return epoch[order], counts, (is_rss[order], xy[order], dz[order], value[order])


def _fill(out: Measurements, i: int, run: _Run, epoch: np.ndarray, counts: np.ndarray, columns: tuple) -> None:
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
    filter (no gate, robust loss, self-calibration, per-wall noise) on uncorrected ranges."""
    bare = all(p.get(k, off) == off for k, off in filter_options.OFF.items())
    return p.get("filter") == "ekf" and p.get("update") == "epoch" and bare \
        and p.get("range_calibration", "none") == "none"


def _shared(p: dict) -> tuple:
    """What cells stepped together must share: motion model, period, coasting limit, window.
    Cells of any measurement kinds and anchor subsets are stepped together (their epochs
    padded to the largest count; position_update costs little per padded row)."""
    return bayes.motion_model(p), p["epoch_s"], p["max_coast_s"], p["init_window_s"] or p["epoch_s"]


@dataclass
class Track:
    """One cell's estimates as bayes.run_filter gives them, without a frame: `rows`
    (estimates, bayes.COLUMNS) as floats (n_meas a count) and the frame's `attrs`."""

    rows: np.ndarray
    attrs: dict

    @classmethod
    def of(cls, estimates: pd.DataFrame) -> "Track":
        """The Track of an estimator's frame, as registry.finish would leave it: the columns
        it lacks NaN, rows sorted by time (stable) when they are not."""
        n = len(estimates)
        rows = np.column_stack([estimates[c].to_numpy(float) if c in estimates else np.full(n, np.nan)
                                for c in bayes.COLUMNS])
        if not estimates["t"].is_monotonic_increasing:
            rows = rows[np.argsort(rows[:, 0], kind="stable")]
        return cls(rows, dict(estimates.attrs))

    def frame(self) -> pd.DataFrame:
        """bayes.run_filter's frame (n_meas as int, attrs)."""
        frame = _frame(self.rows)
        frame.attrs.update(self.attrs)
        return frame

    def finished(self) -> pd.DataFrame:
        """registry.finish(self.frame()) built at once: every column float, in time order already."""
        frame = pd.DataFrame({name: self.rows[:, j] for j, name in enumerate(bayes.COLUMNS)})
        frame.attrs = dict(self.attrs)
        return frame


def stacked(tracks: list[Track], labels: dict[str, list[str]], columns=tuple(bayes.COLUMNS)) -> pd.DataFrame:
    """The tracks one after the other, their `columns` (of bayes.COLUMNS, floats) then each
    label column (labels[name][c] on the rows of track c, strings): pd.concat of the tracks'
    finished frames, each with its labels assigned, built at once from the arrays. attrs:
    the tracks' attrs when they all agree (as pd.concat)."""
    rows = np.concatenate([track.rows for track in tracks])
    track = np.repeat(np.arange(len(tracks)), [len(t.rows) for t in tracks])
    frame = pd.DataFrame({**{name: rows[:, bayes.COLUMNS.index(name)] for name in columns},
                          **{name: pd.array(values, dtype="str")[track] for name, values in labels.items()}})
    if all(t.attrs and t.attrs == tracks[0].attrs for t in tracks):
        frame.attrs = copy.deepcopy(tracks[0].attrs)
    return frame


def run_epoch_ekf(cells: list[tuple[RunData, dict]]) -> list[pd.DataFrame]:
    """bayes.run_filter(data, p) for every (run, resolved parameters) cell with filter ekf and
    update epoch (epoch_ekf_tracks as frames)."""
    return [track.frame() for track in epoch_ekf_tracks(cells)]


def epoch_ekf_tracks(cells: list[tuple[RunData, dict]]) -> list[Track]:
    """bayes.run_filter(data, p) as a Track for every (run, resolved parameters) cell with
    filter ekf and update epoch; the cells that share _shared(p) are stepped together
    (different runs, RSS models and motion detection). attrs as bayes.run_filter's: resets,
    the gate counters (all zero for the bare filter) and the identity range correction."""
    if not all(supports(p) for _, p in cells):
        raise ValueError("run_epoch_ekf steps the epoch-mode EKF only (filter: ekf, update: epoch)")
    groups: dict[tuple, list[int]] = {}
    for i, (_, p) in enumerate(cells):
        groups.setdefault(_shared(p), []).append(i)
    tracks: list[Track | None] = [None] * len(cells)
    for shared, members in groups.items():
        for i, (rows, resets) in zip(members, _step_together([cells[i] for i in members], *shared)):
            attrs = {"resets": resets, **filter_options.UpdateCounts().attrs(),
                     **range_calibration.correction(*cells[i]).describe()}
            tracks[i] = Track(rows, attrs)
    return tracks


def _step_together(cells: list[tuple[RunData, dict]], motion, period: float, max_coast_s: float,
                   window: float) -> list[tuple[np.ndarray, int]]:
    """(estimate rows (bayes.COLUMNS), resets) of every cell, stepped together."""
    runs = [_Run.of(data, p, motion) for data, p in cells]
    meas, row_of = pack(runs, period)
    count = meas.count[row_of]                   # (runs, epochs)
    F, Q, B = motion.matrices(period)
    n_runs, n_epochs = count.shape
    x, P = np.zeros((n_runs, motion.dim)), np.zeros((n_runs, motion.dim, motion.dim))
    started, last_update, resets = np.zeros(n_runs, bool), np.full(n_runs, -np.inf), np.zeros(n_runs, int)
    out = np.full((n_runs, n_epochs, len(bayes.COLUMNS)), np.nan)
    emitted = np.zeros((n_runs, n_epochs), bool)
    lengths = np.array([len(r.times) for r in runs])
    times, static = np.full((n_runs, n_epochs), np.nan), np.ones((n_runs, n_epochs), bool)
    inputs = np.full((n_runs, n_epochs, 2), np.nan)
    for i, r in enumerate(runs):
        times[i, :len(r.times)], static[i, :len(r.times)] = r.times, r.static
        if r.inputs is not None:
            inputs[i, :len(r.times)] = r.inputs
    for k in range(n_epochs):
        live = k < lengths
        t = times[:, k]
        for i in np.flatnonzero(live & ~started):        # the initiator, per run
            fix = runs[i].source.window_fix(t[i], window)
            if fix is not None:
                x[i], P[i] = 0.0, motion.initial_covariance()
                x[i, :2] = fix
                started[i], last_update[i], emitted[i, k] = True, t[i], True
                out[i, k, :7] = (t[i], fix[0], fix[1], P[i, 0, 0], P[i, 0, 1], P[i, 1, 1], 0)
        tracking = live & started & ~emitted[:, k]
        moving = np.flatnonzero(tracking & ~static[:, k])
        if len(moving):
            u = inputs[moving, k]           # a non-finite input: predict without it, as bayes does
            Bu = None if B is None else np.where(np.isfinite(u).all(axis=1)[:, None], np.nan_to_num(u) @ B.T, 0.0)
            x[moving], P[moving] = predict(x[moving], P[moving], F, Q, Bu)
        measured = tracking & (count[:, k] > 0)
        nis = np.full(n_runs, np.nan)
        if measured.any():
            rows = np.flatnonzero(measured)
            x[rows], P[rows], nis[rows] = update(x[rows], P[rows], meas.at(k, row_of[rows]))
            last_update[rows] = t[rows]
        lost = tracking & ~measured & (t - last_update > max_coast_s)
        started[lost] = False
        resets[lost] += 1
        kept = tracking & ~lost
        emitted[kept, k] = True
        out[kept, k] = np.column_stack([t[kept], x[kept, 0], x[kept, 1], P[kept, 0, 0], P[kept, 0, 1], P[kept, 1, 1],
                                        np.where(measured[kept], count[kept, k], 0), nis[kept]])
    return [(out[i, emitted[i]], int(resets[i])) for i in range(n_runs)]


def _frame(rows: np.ndarray) -> pd.DataFrame:
    """bayes.COLUMNS of the (estimates, columns) array `rows`, n_meas as int (column by column:
    a frame of one float block cast afterwards costs several times more)."""
    return pd.DataFrame({name: rows[:, j].astype(int) if name == "n_meas" else rows[:, j]
                         for j, name in enumerate(bayes.COLUMNS)})


def kalman_tracks(fix_tables: list[pd.DataFrame], matrices: tuple) -> list[pd.DataFrame]:
    """trackers.kalman_track(fixes, matrices) for every table of per-epoch fixes (t, x, y;
    NaN without a fix), stepped together: a run starts at its first fix, predicts at every
    later epoch of its grid and is updated with each fix (z = H x + v); output at its fixes."""
    F, Q, H, R, P0 = matrices
    n_runs, n_epochs = len(fix_tables), max([len(f) for f in fix_tables] + [0])
    t, z = np.full((n_runs, n_epochs), np.nan), np.full((n_runs, n_epochs, 2), np.nan)
    for i, f in enumerate(fix_tables):
        t[i, :len(f)], z[i, :len(f)] = f["t"].to_numpy(float), f[["x", "y"]].to_numpy(float)
    live, has_fix = np.arange(n_epochs)[None, :] < np.array([len(f) for f in fix_tables])[:, None], \
        np.isfinite(z).all(axis=2)
    x, P, started = np.zeros((n_runs, 4)), np.zeros((n_runs, 4, 4)), np.zeros(n_runs, bool)
    out = np.full((n_runs, n_epochs, 6), np.nan)
    for k in range(n_epochs):
        rolling = np.flatnonzero(started & live[:, k])
        x[rolling], P[rolling] = predict(x[rolling], P[rolling], F, Q)
        first = has_fix[:, k] & ~started
        x[first], P[first], started[first] = np.column_stack([z[first, k], np.zeros((first.sum(), 2))]), P0, True
        rows = np.flatnonzero(has_fix[:, k] & ~first)
        if len(rows):
            x[rows], P[rows], _ = joseph_update(x[rows], P[rows], z[rows, k] - x[rows] @ H.T, H[None], R[None])
        out[:, k] = np.column_stack([t[:, k], x[:, 0], x[:, 1], P[:, 0, 0], P[:, 0, 1], P[:, 1, 1]])
    return [pd.DataFrame(out[i, has_fix[i]], columns=["t", "x", "y", "p_xx", "p_xy", "p_yy"]) for i in range(n_runs)]


def run_many(name: str, datas: list[RunData], overrides: dict | None = None, where: str = "") -> list[pd.DataFrame]:
    """registry.run(name, data, overrides, where) for every run of `datas` (run_cells)."""
    return run_cells(name, [(data, overrides or {}) for data in datas], where)


def run_cells(name: str, cells: list[tuple[RunData, dict]], where: str = "") -> list[pd.DataFrame]:
    """[registry.run(name, data, overrides, where) for data, overrides in cells] (e.g. every run
    x row of a paper's table): the epoch-mode EKF cells and the KF over fixes (kf_tracker) are
    stepped together, so the Python loop over epochs runs once for all of them (per group of
    cells sharing a motion model or KF matrices); other estimators run one cell at a time."""
    estimator = registry.get(name)
    params = [estimator.resolve(overrides, where) for _, overrides in cells]
    if _epoch_ekf(estimator, params):
        return [track.finished() for track in epoch_ekf_tracks([(data, p) for (data, _), p in zip(cells, params)])]
    if name == "kf_tracker":
        return [registry.finish(frame) for frame in _kalman_cells([data for data, _ in cells], params)]
    return [registry.run(name, data, overrides, where) for data, overrides in cells]


def cell_tracks(name: str, cells: list[tuple[RunData, dict]], where: str = "") -> list[Track]:
    """run_cells(name, cells, where) as Tracks (the bayes.COLUMNS arrays and attrs of each
    cell), stepped together as there; no registry.finish frame is built per cell (the
    epoch-mode EKF builds no frame at all)."""
    estimator = registry.get(name)
    params = [estimator.resolve(overrides, where) for _, overrides in cells]
    if _epoch_ekf(estimator, params):
        return epoch_ekf_tracks([(data, p) for (data, _), p in zip(cells, params)])
    if name == "kf_tracker":
        return [Track.of(frame) for frame in _kalman_cells([data for data, _ in cells], params)]
    return [Track.of(estimator.function(data, p)) for (data, _), p in zip(cells, params)]


def _epoch_ekf(estimator: registry.Estimator, params: list[dict]) -> bool:
    """Whether every cell is the epoch-mode EKF that epoch_ekf_tracks steps."""
    return estimator.function is bayes.run_filter and all(supports(p) for p in params)


def _kalman_cells(datas: list[RunData], params: list[dict]) -> list[pd.DataFrame]:
    """kf_tracker of every (run, resolved parameters) cell: cells with the same KF matrices are
    stepped together (kalman_tracks)."""
    groups: dict[tuple, list[int]] = {}
    for i, p in enumerate(params):
        key = (p["epoch_s"], p["accel_sigma_mps2"], p["position_sigma_m"], p["initial_speed_sigma_mps"])
        groups.setdefault(key, []).append(i)
    frames: list[pd.DataFrame] = [pd.DataFrame()] * len(params)
    for key, members in groups.items():
        tracks = kalman_tracks([fixes.epoch_fixes(datas[i], params[i], params[i]["fixes"]) for i in members],
                               trackers.kalman_matrices(*key))
        for i, track in zip(members, tracks):
            frames[i] = track
    return frames
