"""The filter core: one loop per update mode, written once, and the components it is made of.

As in Stone Soup's trackers, the loop only sequences; what it does at each step is passed in:
- an **initiator** (`WindowInitiator`): when and where a track starts,
  initiate(source, t, motion) -> (x0, P0) or None;
- a **deleter** (`CoastingDeleter`): when a track is dropped (a reset; the initiator restarts
  it), delete(t, last_update, lost) -> bool (element-wise on arrays);
- a **bank** of filters, one per run, that predicts and updates: `FilterBank` (any filter of
  bayes.FILTERS, with the measurement-update options of filter_options, whose gate and robust
  update are themselves a pluggable `updater`) or the array EKF (estimators.array_ekf: the bare
  EKF of many runs in a few array operations per epoch). A bank has
  start(i, x0, P0, motion), predict(rows, F, Q, B, u), update(rows, k) -> (used, nis, lost),
  estimates(rows) -> (rows, 5) [x, y, p_xx, p_xy, p_yy] (+ [z, p_zz] with a 3-D state: (rows, 7))
  and track(i) (an object with x, P).

Update modes
- `epoch_loop`: runs on a leading run axis (a single run is a batch of one). Run r's k-th
  epoch is step k; per epoch: start the tracks not running (initiator; the start is output
  as the estimate of that epoch, n_meas 0), predict the others over the period T (skipped in
  static epochs: motion detection, paper A), update them with the epoch's measurements, set
  their last update time when a measurement was used and drop those the deleter deletes;
  output the rest at t_k. An input-dependent motion model (odometry) is predicted run by run
  with its own F(u).
- `sequential_loop` (one run): predicts to each measurement group's own time and updates with
  it (records sharing a time stamp update together; the source's group_models, built once);
  before each group and at each output time t_k the deleter is asked; output at t_k predicted
  from the last update (x(t_k) = F(t_k - t) x (+ B u), P(t_k) = F P F^T + Q(t_k - t), not stored). With an
  input-dependent motion model (odometry) the filter is instead predicted to every t_k with
  that epoch's input (stored), so a gap is bridged epoch by epoch with each epoch's odometry.
Both return a `Track` per run: rows of COLUMNS (COLUMNS_3D with a 3-D state) and the number of
resets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

COLUMNS = ["t", "x", "y", "p_xx", "p_xy", "p_yy", "n_meas", "nis"]
COLUMNS_3D = COLUMNS + ["z", "p_zz"]        # a 3-D state's estimates: height (m) and its variance (m^2)
# m: position sigma sqrt(p_xx + p_yy) above which an estimate is not output (withhold_uncertain). Above
# the steady state of every filter measured: at most 2.6 m on the shared real runs (BLE RSS alone; the
# outdoor UWB 1.7 m) and 1.9 m on the simulated campaigns, so it acts on tracks coasting through a
# gap, whose sigma grows as q dt^3 / 3 per axis (10 s at 0.5 m/s^2: 7 m) while a walker turns away
# from the prediction (2026-12-07: on 16 simulated walks with two gaps RMSE 0.97-1.35 -> 0.21-0.29 m,
# median unchanged, availability 0.69-0.70 -> 0.65-0.66, docs/realdata.md).
MAX_POSITION_SIGMA_M = 4.0


def columns(dimensions: int) -> list[str]:
    """The estimate columns of a state with 2 or 3 position axes."""
    return COLUMNS_3D if dimensions == 3 else COLUMNS


# ---- components ----------------------------------------------------------------------------
@dataclass(frozen=True)
class WindowInitiator:
    """Starts a track the first time the measurements of the last `window_s` seconds
    (per-anchor means, MeasurementSource.window_fix) give a multilateration fix: x0 = [fix, 0...]
    (speed and bias 0; the fix in the motion model's 2 or 3 axes), P0 = the motion model's
    initial covariance. With `longest_s` above window_s, where the window holds too few anchors
    for a fix it is doubled, up to longest_s: ranges that come one anchor at a time at a few Hz
    rarely hold three anchors in one period (a 0.5 s epoch at 2-4 Hz never did, and such a run
    had no estimate at all), while a run whose periods hold a fix starts as before."""

    window_s: float
    longest_s: float = 0.0

    def initiate(self, source, t: float, motion) -> tuple[np.ndarray, np.ndarray] | None:
        window = self.window_s
        fix = source.window_fix(t, window, motion.dimensions)
        while fix is None and window < self.longest_s:
            window = min(2.0 * window, self.longest_s)
            fix = source.window_fix(t, window, motion.dimensions)
        if fix is None:
            return None
        x0 = np.zeros(motion.dim)
        x0[:len(fix)] = fix
        return x0, motion.initial_covariance()


@dataclass(frozen=True)
class CoastingDeleter:
    """Coasting limit: a track is deleted after more than `max_coast_s` seconds without an
    update (t - last_update > max_coast_s; in sequential mode without a supported update,
    Support), or when its updater found it lost (the gate rejecting most measurements,
    filter_options.ConfiguredFilter.lost), so a long gap shows as lower availability instead of
    unbounded drift. Works on scalars and on arrays of runs."""

    max_coast_s: float

    def delete(self, t, last_update, lost):
        return lost | (t - last_update > self.max_coast_s)


class Support:
    """When a sequential track's position was last supported: `since`, the last used measurement
    of an anchor other than the most recently used one (the track's start counts: its fix
    determined the position). Ranges (or RSS) of one anchor alone constrain the distance to it,
    not the bearing, yet a filter linearised at a moving estimate reads bearing information into
    them and reports a covariance far too small (a walk ranged by one anchor for 30 s: errors up to
    8-18 m, 9-71 outputs beyond 3 position sigmas, tests/test_estimators.py); the deleter counts
    such a stretch as coasting. A TDOA record's id is its pair (one pair: a hyperbola). Sequential
    mode only: epoch updates serve synchronous rounds, where every epoch holds every anchor heard.
    (Not the covariance: restarting a track whose sigma stays large while it takes measurements
    helped a UKF that diverged on a 2 Hz walk, but on range differences far from a small anchor
    cluster each restart started from a hyperbolic fix tens of metres off with the initial 2 m
    sigma: cucudasluv nlos/a-case-1 as TDOA, tracker RMSE 29.5 m against 1.3 m without it.)"""

    def __init__(self, t: float):
        self.last_id, self.last_t, self.since = None, t, t

    def use(self, ids, t: float) -> None:
        """Measurements of the anchors `ids` were used at t (s)."""
        for anchor in ids:
            if anchor != self.last_id:
                self.since, self.last_id = self.last_t, anchor
            self.last_t = t


def _used_ids(anchors: list, records, a: int, b: int, filt) -> list:
    """The anchor ids of records a..b-1 that the update used: all but those the filter's gate left
    out (ConfiguredFilter.kept, in the model's order: the ranges, then the RSS, Records.split);
    all where the model's rows are not the records' (a TDOA update leaves redundant pairs out)."""
    if b - a == 1:
        return anchors[a:b]
    r_ids, _, s_ids, _ = records.split(a, b)
    ids = list(r_ids) + list(s_ids)
    kept = getattr(filt, "kept", None)
    return [i for i, k in zip(ids, kept) if k] if kept is not None and len(kept) == len(ids) else ids


def predict_step(filt, F: np.ndarray, Q: np.ndarray, B: np.ndarray | None, u: np.ndarray | None) -> tuple:
    """Predict `filt` with (F, Q) and the input B u when there is one and u is finite; returns
    the step (F, Q, B, u) used (B, u None without input), as the smoother records it."""
    if B is not None and u is not None and np.all(np.isfinite(u)):
        filt.predict(F, Q, u=u, B=B)
        return F, Q, B, u
    filt.predict(F, Q)
    return F, Q, None, None


def update_step(filt, model) -> tuple[int, float, bool]:
    """Measurement update of one filter with a measurement model: (used, nis, lost). used: the
    measurements the update kept (`filt.used` of a gated filter, else all); 0 when the gate
    rejected every one (no update) or found the track lost; nis NaN when none was used."""
    filt.update_model(model)
    lost = getattr(filt, "lost", False)
    used = 0 if lost else getattr(filt, "used", len(model.z))
    return used, (filt.nis if used else np.nan), lost


# ---- what a loop reads and writes ----------------------------------------------------------------
@dataclass
class RunInputs:
    """What the loops read of one run: epoch end times t_k (s), measurement source, static
    epochs (motion detection) and PVA inputs per epoch (None without)."""

    times: np.ndarray
    source: object
    static: np.ndarray
    inputs: np.ndarray | None


@dataclass
class Track:
    """One run's estimates as a filter gives them: `rows` (estimates, COLUMNS) as floats
    (n_meas a count) and the frame's `attrs` (resets and the update counters)."""

    rows: np.ndarray
    attrs: dict

    @property
    def columns(self) -> list[str]:
        """COLUMNS, or COLUMNS_3D for the rows of a 3-D state."""
        return COLUMNS_3D if self.rows.shape[1] == len(COLUMNS_3D) else COLUMNS

    @classmethod
    def of(cls, estimates: pd.DataFrame) -> "Track":
        """The Track of an estimator's frame, as registry.finish would leave it: the columns
        it lacks NaN (COLUMNS_3D for a frame with z), rows sorted by time (stable) when they are not."""
        n = len(estimates)
        rows = np.column_stack([estimates[c].to_numpy(float) if c in estimates else np.full(n, np.nan)
                                for c in (COLUMNS_3D if "z" in estimates else COLUMNS)])
        if not estimates["t"].is_monotonic_increasing:
            rows = rows[np.argsort(rows[:, 0], kind="stable")]
        return cls(rows, dict(estimates.attrs))

    def frame(self) -> pd.DataFrame:
        """The filter's frame: COLUMNS, n_meas as int (column by column: a frame of one float
        block cast afterwards costs several times more), attrs."""
        frame = pd.DataFrame({name: self.rows[:, j].astype(int) if name == "n_meas" else self.rows[:, j]
                              for j, name in enumerate(self.columns)})
        frame.attrs.update(self.attrs)
        return frame

    def finished(self) -> pd.DataFrame:
        """registry.finish(self.frame()) built at once: every column float, in time order already."""
        frame = pd.DataFrame({name: self.rows[:, j] for j, name in enumerate(self.columns)})
        frame.attrs = dict(self.attrs)
        return frame


class FilterBank:
    """One filter object per run (made by makes[i](x0, P0, motion) at each start), stepped one
    after the other; the measurements of run i's epoch k are models[i][k] (None: none)."""

    def __init__(self, makes: list, models: list[list]):
        self.makes, self.models = makes, models
        self.filters: list = [None] * len(makes)
        self.axes = 2

    def start(self, i: int, x0: np.ndarray, P0: np.ndarray, motion) -> None:
        self.filters[i], self.axes = self.makes[i](x0, P0, motion), motion.dimensions

    def track(self, i: int):
        return self.filters[i]

    def predict(self, rows: np.ndarray, F, Q, B, u: np.ndarray | None) -> list[tuple]:
        """predict_step of each row's filter; the steps used."""
        return [predict_step(self.filters[i], F, Q, B, None if u is None else u[j]) for j, i in enumerate(rows)]

    def update(self, rows: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        steps = [(0, np.nan, False) if self.models[i][k] is None else update_step(self.filters[i], self.models[i][k])
                 for i in rows]
        used, nis, lost = (np.array(column) for column in zip(*steps)) if steps else ([], [], [])
        return np.asarray(used, dtype=int), np.asarray(nis, dtype=float), np.asarray(lost, dtype=bool)

    def estimates(self, rows: np.ndarray) -> np.ndarray:
        width = 5 if self.axes == 2 else 7
        return np.array([_position(self.filters[i].x, self.filters[i].P, self.axes)
                         for i in rows]).reshape(len(rows), width)


def withhold_uncertain(rows: np.ndarray, limit: float, anchor_xy: np.ndarray | None = None,
                       reach: float = np.inf) -> tuple[np.ndarray, int]:
    """(rows (COLUMNS first) without those whose position sigma sqrt(p_xx + p_yy) (m) exceeds
    `limit` or whose position lies further than `reach` (m, max_range_m) from every anchor of
    `anchor_xy` (m, (n, 2); anchors without a position ignored), how many were left out); limit 0:
    every row. A coasting track's prediction is an estimate in name only once its sigma passes the
    filter's steady state (MAX_POSITION_SIGMA_M); a position no anchor's range reaches contradicts
    the measurements themselves (beyond_reach: a particle cloud on range differences far from a
    small anchor cluster settled 158-492 m out, the truth within 49 m, at a sigma of 1.3-3.9 m).
    Their rows stay out of the output and of the metrics, and the availability shows the gap."""
    if limit <= 0 or not len(rows):
        return rows, 0
    keep = ~(np.sqrt(rows[:, COLUMNS.index("p_xx")] + rows[:, COLUMNS.index("p_yy")]) > limit)
    if anchor_xy is not None:
        keep &= ~beyond_reach(rows[:, 1:3], anchor_xy, reach)
    return (rows, 0) if keep.all() else (rows[keep], int((~keep).sum()))


def beyond_reach(xy: np.ndarray, anchor_xy: np.ndarray, reach: float) -> np.ndarray:
    """Per position of xy ((n, 2), m): whether it lies further than `reach` (m, max_range_m) from
    every anchor of anchor_xy ((k, 2), m; anchors without a position ignored), where no range could
    come from; all False without an anchor or with an infinite reach."""
    anchor_xy = anchor_xy[np.all(np.isfinite(anchor_xy), axis=1)]
    if not len(anchor_xy) or not np.isfinite(reach):
        return np.zeros(len(xy), dtype=bool)
    return np.hypot(xy[:, None, 0] - anchor_xy[None, :, 0], xy[:, None, 1] - anchor_xy[None, :, 1]).min(axis=1) > reach


def _position(x: np.ndarray, P: np.ndarray, axes: int = 2) -> tuple:
    """(x, y, p_xx, p_xy, p_yy), with (z, p_zz) after them for a 3-D state (axes 3)."""
    return (x[0], x[1], P[0, 0], P[0, 1], P[1, 1]) + ((x[2], P[2, 2]) if axes == 3 else ())


def _put(out: np.ndarray, rows, k: int, t, estimates: np.ndarray, used, nis) -> None:
    """Write the estimate rows (columns(axes)) of `rows` at epoch k: t, the bank's estimates
    (rows, 5 or 7: x, y, p_xx, p_xy, p_yy [, z, p_zz]), n_meas and nis."""
    out[rows, k, 0], out[rows, k, 1:6], out[rows, k, 6], out[rows, k, 7] = t, estimates[:, :5], used, nis
    if estimates.shape[1] > 5:
        out[rows, k, 8:] = estimates[:, 5:]


# ---- the loops -----------------------------------------------------------------------------------
def epoch_loop(bank, runs: list[RunInputs], motion, period: float, initiator, deleter,
               forward=None) -> list[tuple[np.ndarray, int]]:
    """(estimate rows (COLUMNS), resets) of every run, stepped together (module docstring).
    forward: a smoothing.ForwardPass recording a single run's filter (a FilterBank of one)."""
    if forward is not None and len(runs) != 1:
        raise ValueError("the forward pass records one run")
    n_runs = len(runs)
    lengths = np.array([len(r.times) for r in runs], dtype=int)
    n_epochs = int(lengths.max(initial=0))
    times, static = np.full((n_runs, n_epochs), np.nan), np.ones((n_runs, n_epochs), bool)
    with_input = any(r.inputs is not None for r in runs)
    inputs = np.full((n_runs, n_epochs, 2), np.nan) if with_input else None
    for i, r in enumerate(runs):
        times[i, :len(r.times)], static[i, :len(r.times)] = r.times, r.static
        if r.inputs is not None:
            inputs[i, :len(r.times)] = r.inputs
    F, Q, B = motion.matrices(period)
    here = np.arange(n_epochs)[None, :] < lengths[:, None]
    live, last_update, resets = np.zeros(n_runs, bool), np.full(n_runs, -np.inf), np.zeros(n_runs, int)
    out = np.full((n_runs, n_epochs, len(columns(motion.dimensions))), np.nan)
    emitted = np.zeros((n_runs, n_epochs), bool)
    for k in range(n_epochs):
        t, tracking = times[:, k], here[:, k] & live
        waiting = here[:, k] & ~live
        if waiting.any():
            for i in np.flatnonzero(waiting):
                prior = initiator.initiate(runs[i].source, t[i], motion)
                if prior is None:
                    continue
                bank.start(i, *prior, motion)
                live[i], last_update[i], emitted[i, k] = True, t[i], True
                _put(out, i, k, t[i], bank.estimates([i]), 0, np.nan)
                if forward is not None:
                    forward.start(bank.track(i))
                    forward.output()
        rows = np.flatnonzero(tracking)
        if not len(rows):
            continue
        moving = rows[~static[rows, k]]
        if motion.input_dependent:      # F(u) of each run's own input
            steps = [bank.predict(moving[j:j + 1], *motion.matrices(period, inputs[i, k]), inputs[i:i + 1, k])[0]
                     for j, i in enumerate(moving)]
        else:
            steps = bank.predict(moving, F, Q, B, None if inputs is None else inputs[moving, k])
        used, nis, lost = bank.update(rows, k)
        updated = rows[used > 0]
        last_update[updated] = t[updated]
        drop = deleter.delete(t[rows], last_update[rows], lost)
        if drop.any():
            live[rows[drop]] = False
            resets[rows[drop]] += 1
            rows, used, nis = rows[~drop], used[~drop], nis[~drop]
        emitted[rows, k] = True
        _put(out, rows, k, t[rows], bank.estimates(rows), used, nis)
        if forward is not None and len(rows):
            forward.node(bank.track(0), steps[0] if len(moving) else None)
            forward.output()
    return [(out[i, emitted[i]], int(resets[i])) for i in range(n_runs)]


def sequential_loop(make, run: RunInputs, motion, initiator, deleter, forward=None) -> tuple[np.ndarray, int]:
    """(estimate rows (COLUMNS), resets) of one run in sequential mode (module docstring);
    make(x0, P0, motion): a filter."""
    source, times, static, inputs = run.source, np.asarray(run.times, dtype=float), run.static, run.inputs
    records = source.records()
    bounds, models = records.groups().tolist(), source.group_models
    epoch_of = np.minimum(np.searchsorted(times, records.t, side="left"), len(times) - 1)   # (t_k - T, t_k]
    # the loop reads scalars: Python numbers index and compare faster than numpy scalars (same values)
    record_t, moving, epoch_of = records.t.tolist(), (~np.asarray(static, dtype=bool)).tolist(), epoch_of.tolist()
    anchors = records.anchor.tolist()
    rows, resets, filt, t_filter, support = [], 0, None, -np.inf, None
    g = 0
    for k, t_k in enumerate(times.tolist()):
        n_meas, nis = 0, np.nan
        while g < len(bounds) - 1 and record_t[bounds[g]] <= t_k:
            a, b, model = bounds[g], bounds[g + 1], models[g]
            t = record_t[a]
            g += 1
            if filt is not None and deleter.delete(t, support.since, False):
                filt, resets = None, resets + 1
            if filt is None:
                prior = initiator.initiate(source, t, motion)
                if prior is not None:
                    filt, t_filter, support = make(*prior, motion), t, Support(t)
                    if forward is not None:
                        forward.start(filt)
                continue
            step = None
            if t > t_filter and moving[epoch_of[a]]:
                u = None if inputs is None else inputs[epoch_of[a]]
                F, Q, B = motion.matrices(t - t_filter, u)
                step = predict_step(filt, F, Q, B, u)
            t_filter = max(t, t_filter)
            used, group_nis, lost = update_step(filt, model)
            if used:
                n_meas, nis = n_meas + used, group_nis
                support.use(_used_ids(anchors, records, a, b, filt), t)
            if deleter.delete(t, support.since, lost):
                filt, resets = None, resets + 1
                continue
            if forward is not None:
                forward.node(filt, step)
        if filt is None:
            continue
        if deleter.delete(t_k, support.since, False):
            filt, resets = None, resets + 1
            continue
        u = None if inputs is None else inputs[k]
        if forward is not None or motion.input_dependent:
            # smoothing: the output time becomes a node of the recorded chain; odometry: the
            # filter follows every epoch's input (module docstring)
            if t_k > t_filter and moving[k]:
                F, Q, B = motion.matrices(t_k - t_filter, u)
                step = predict_step(filt, F, Q, B, u)
                if forward is not None:
                    forward.node(filt, step)
                t_filter = t_k
            if forward is not None:
                forward.output()
        x, P = filt.x[:motion.dim], filt.P[:motion.dim, :motion.dim]      # without calibration states
        if t_k > t_filter and moving[k]:
            F, Q, B = motion.matrices(t_k - t_filter, u)
            x, P = F @ x, F @ P @ F.T + Q
            if B is not None and u is not None and np.all(np.isfinite(u)):
                x = x + B @ u
        position = _position(x, P, motion.dimensions)
        rows.append((t_k, *position[:5], n_meas, nis, *position[5:]))
    return np.array(rows, dtype=float).reshape(len(rows), len(columns(motion.dimensions))), resets
