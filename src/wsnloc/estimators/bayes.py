"""Bayesian filters assembled from parts: motion model, measurement models, update mode,
initiator, coasting limit and optional motion detection (papers A and C, and any dataset).

Update modes
- `epoch`: one predict (step T) and one update per estimation period with the epoch's
  measurements (per-anchor means), as in papers A and C; output at every epoch end t_k.
- `sequential`: the filter predicts to each measurement's own time and updates with it
  (records sharing a time stamp update together), so ranges that arrive one anchor at a
  time are used as they come; output at the same epoch ends t_k, predicted from the
  last update (x(t_k) = F(t_k - t) x, P(t_k) = F P F^T + Q(t_k - t), not stored).
  When every measurement of an epoch carries the time t_k, both modes give the same
  estimates.
Initiator: the first time the measurements of the last `init_window_s` seconds (per-anchor
  means) give a multilateration fix, the state starts there (speed and bias 0, P0).
Coasting limit: after `max_coast_s` seconds without an update (or when the innovation gate
  finds the track lost, estimators.filter_options) the track is dropped (counted as a
  reset) and restarted by the initiator; no estimate is output meanwhile,
  so a long gap shows as lower availability instead of unbounded drift.
Motion detection (paper A): in epochs declared static by the accelerometer the predict
  step is skipped (state and covariance frozen).
Filters (`FILTERS`, parameter `filter`): `ekf` (filters.kalman), `ukf` (scaled sigma points,
  filters.ukf: alpha, beta, kappa) and `pf` (bootstrap particle filter, filters.particle:
  n_particles, resample_threshold, outlier_probability, outlier_span_m, seed); all share the
  predict(F, Q, u, B) / update_model(model) interface, so every loop above runs any of them.
  The particle filter draws from one numpy Generator per run, seeded with
  (seed, CRC-32 of the run's name): reproducible, and independent between runs.
Smoothing (`run_smoother`): the forward pass is recorded (smoothing.ForwardPass) and the
  fixed-interval RTS smoother runs over each track segment offline; see smoothing.py.
"""

from __future__ import annotations

import zlib

import numpy as np
import pandas as pd

from wsnloc.errors import ConfigError
from wsnloc.estimators import range_calibration
from wsnloc.estimators.filter_options import UpdateCounts, configured_factory
from wsnloc.estimators.inertial import epoch_inputs, floor_input
from wsnloc.estimators.measurements import MeasurementSource, rss_params
from wsnloc.estimators.motion import MotionModel
from wsnloc.estimators.run_data import RunData
from wsnloc.estimators.smoothing import ForwardPass
from wsnloc.filters.kalman import ExtendedKalmanFilter
from wsnloc.filters.particle import ParticleFilter
from wsnloc.filters.ukf import UnscentedKalmanFilter
from wsnloc.inertial.motion_detection import static_epochs

COLUMNS = ["t", "x", "y", "p_xx", "p_xy", "p_yy", "n_meas", "nis"]


def ekf_factory(p: dict, data: RunData):
    def make(x0: np.ndarray, P0: np.ndarray, motion: MotionModel):
        F, Q, _ = motion.matrices(motion.period_s)
        return ExtendedKalmanFilter(x0, P0, F, Q)
    return make


def ukf_factory(p: dict, data: RunData):
    def make(x0: np.ndarray, P0: np.ndarray, motion: MotionModel):
        return UnscentedKalmanFilter(x0, P0, p["alpha"], p["beta"], p["kappa"])
    return make


def run_generator(seed: int, data: RunData) -> np.random.Generator:
    """The random stream of one run: numpy Generator seeded with (seed, CRC-32 of the run's name)."""
    return np.random.default_rng([seed, zlib.crc32(data.name.encode())])


def pf_factory(p: dict, data: RunData):
    rng = run_generator(p["seed"], data)           # one stream per run: a restarted track continues it

    def make(x0: np.ndarray, P0: np.ndarray, motion: MotionModel):
        return ParticleFilter(x0, P0, p["n_particles"], rng, p["resample_threshold"], p["outlier_probability"],
                              p["outlier_span_m"])
    return make


# filter name -> factory(parameters, run) -> make(x0, P0, motion) -> a filter with x, P, nis,
# predict(F, Q, u, B) and update_model(model)
FILTERS = {"ekf": ekf_factory, "ukf": ukf_factory, "pf": pf_factory}


class Track:
    """Output rows and counters of one filter run."""

    def __init__(self):
        self.rows: list[tuple] = []
        self.resets = 0

    def emit(self, t: float, x: np.ndarray, P: np.ndarray, n_meas: int, nis: float) -> None:
        self.rows.append((t, x[0], x[1], P[0, 0], P[0, 1], P[1, 1], n_meas, nis))

    def frame(self) -> pd.DataFrame:
        out = pd.DataFrame(self.rows, columns=COLUMNS)
        out.attrs["resets"] = self.resets
        return out


def motion_model(p: dict) -> MotionModel:
    return MotionModel(p["motion"], p["epoch_s"], p["p_sigma_m"], p["accel_sigma_mps2"], p["bias_walk_sigma"],
                       p["initial_sigma_m"], p["initial_speed_sigma_mps"], p["initial_bias_sigma_mps2"])


def measurement_source(data: RunData, p: dict) -> MeasurementSource:
    """The measurements (and their models) a filter with parameters p reads from the run, the
    ranges corrected by the configured range calibration (range_calibration.correction)."""
    args = (p["measurements"], p["anchors"], p["range_sigma_m"], p["preliminary_filter"], p["max_range_m"],
            rss_params(data, p) if p["measurements"] != "toa" else None, range_calibration.correction(data, p))
    return data.cached(("measurement_source",) + args, lambda: MeasurementSource(data, *args))


def static_flags(data: RunData, p: dict, times: np.ndarray) -> np.ndarray:
    """Per epoch ending at times: True where motion detection (if enabled) skips the predict
    step; computed once per run and setting (the rows of a paper share it)."""
    if not p["motion_detection"]:
        return np.zeros(len(times), dtype=bool)
    return data.cached(("static_epochs", p["epoch_s"], p["motion_threshold_mps2"], p["static_start_s"], len(times)),
                       lambda: static_epochs(data.require("imu", "motion detection"), times, p["epoch_s"],
                                             p["motion_threshold_mps2"], p["static_start_s"]))


def filter_inputs(data: RunData, p: dict, motion: MotionModel) -> tuple:
    """(measurement source, epoch end times, static flags, PVA inputs or None) that a filter
    with parameters p reads from the run (shared with the batched EKF, estimators.batched)."""
    source = measurement_source(data, p)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    inputs = epoch_inputs(floor_input(data, p["static_start_s"]), times) if motion.kind == "pva" else None
    return source, times, static_flags(data, p, times), inputs


def run_filter(data: RunData, p: dict) -> pd.DataFrame:
    """Estimates (COLUMNS) of one run; `attrs`: resets (coasting-limit resets), gated / offered
    measurements and gated_share (filter_options), the self-calibration states range_scale /
    range_offset_m, and the range calibration applied (range_calibration.RangeCorrection.describe)."""
    return _run(data, p, None)


def run_smoother(data: RunData, p: dict) -> pd.DataFrame:
    """The fixed-interval RTS-smoothed estimates of one run (same rows as the forward pass;
    n_meas and nis are the forward pass's). In sequential mode the recorded forward pass
    steps the filter to every output time (see smoothing.py)."""
    if p.get("range_self_calibration", "none") != "none":
        raise ConfigError("range_self_calibration: the RTS smoothers do not smooth the calibration states; "
                          "use range_calibration (donor or configured) with a smoother")
    forward = ForwardPass()
    out = _run(data, p, forward)
    smoothed = forward.smooth()
    if len(out):
        xs = np.array([x for x, _ in smoothed])
        Ps = np.array([P for _, P in smoothed])
        out["x"], out["y"] = xs[:, 0], xs[:, 1]
        out["p_xx"], out["p_xy"], out["p_yy"] = Ps[:, 0, 0], Ps[:, 0, 1], Ps[:, 1, 1]
    return out


def _run(data: RunData, p: dict, forward: ForwardPass | None) -> pd.DataFrame:
    motion = motion_model(p)
    source, times, static, inputs = filter_inputs(data, p, motion)
    counts = UpdateCounts()
    make = configured_factory(FILTERS[p["filter"]](p, data), p, counts, data.campaign)
    loop = _epoch_loop if p["update"] == "epoch" else _sequential_loop
    out = loop(source, times, p, motion, static, inputs, make, forward)
    out.attrs.update(counts.attrs())
    out.attrs.update(source.correction.describe())
    return out


def _update(filt, model) -> int:
    """Measurement update; the number of measurements used: 0 when the gate rejected every
    one (no update) or found the track lost (filter_options.ConfiguredFilter.lost; the loops
    drop it then)."""
    filt.update_model(model)
    return 0 if _lost(filt) else getattr(filt, "used", len(model.z))


def _lost(filt) -> bool:
    return getattr(filt, "lost", False)


def _start(fix: np.ndarray, motion: MotionModel, make, forward: ForwardPass | None):
    x0 = np.zeros(motion.dim)
    x0[:2] = fix
    filt = make(x0, motion.initial_covariance(), motion)
    if forward is not None:
        forward.start(filt)
    return filt


def _predict(filt, motion: MotionModel, dt: float, u: np.ndarray | None) -> tuple:
    """Predict over dt (s) with the input u when it is finite; returns the step (F, Q, B, u) used."""
    F, Q, B = motion.matrices(dt)
    if B is not None and u is not None and np.all(np.isfinite(u)):
        filt.predict(F, Q, u=u, B=B)
        return F, Q, B, u
    filt.predict(F, Q)
    return F, Q, None, None


def _epoch_loop(source, times, p, motion, static, inputs, make, forward) -> pd.DataFrame:
    period, window = p["epoch_s"], p["init_window_s"] or p["epoch_s"]
    models = source.epoch_models(times, period)
    track, filt, last_update = Track(), None, -np.inf
    for k, (t, model) in enumerate(zip(times, models)):
        if filt is None:
            fix = source.window_fix(t, window)
            if fix is None:
                continue
            filt, last_update = _start(fix, motion, make, forward), t
            track.emit(t, filt.x, filt.P, 0, np.nan)
            if forward is not None:
                forward.output()
            continue
        step = None if static[k] else _predict(filt, motion, period, None if inputs is None else inputs[k])
        nis, used = np.nan, 0 if model is None else _update(filt, model)
        if used:
            nis, last_update = filt.nis, t
        elif t - last_update > p["max_coast_s"] or _lost(filt):
            filt = None
            track.resets += 1
            continue
        track.emit(t, filt.x, filt.P, used, nis)
        if forward is not None:
            forward.node(filt, step)
            forward.output()
    return track.frame()


def _sequential_loop(source, times, p, motion, static, inputs, make, forward) -> pd.DataFrame:
    records = source.records()
    bounds = records.groups()
    window = p["init_window_s"] or p["epoch_s"]
    epoch_of = np.searchsorted(times, records.t, side="left")        # epoch (t_k - T, t_k] of each record
    track, filt, t_filter, last_update = Track(), None, -np.inf, -np.inf
    g = 0
    for k, t_k in enumerate(times):
        n_meas, nis = 0, np.nan
        while g < len(bounds) - 1 and records.t[bounds[g]] <= t_k:
            a, b = bounds[g], bounds[g + 1]
            t = records.t[a]
            g += 1
            if filt is not None and t - last_update > p["max_coast_s"]:
                filt = None
                track.resets += 1
            if filt is None:
                fix = source.window_fix(t, window)
                if fix is not None:
                    filt, t_filter, last_update = _start(fix, motion, make, forward), t, t
                continue
            step = None
            if t > t_filter and not static[min(epoch_of[a], len(times) - 1)]:
                step = _predict(filt, motion, t - t_filter,
                                None if inputs is None else inputs[min(epoch_of[a], len(times) - 1)])
            t_filter = max(t, t_filter)
            used = _update(filt, source.model(*records.split(a, b)))
            if used:
                n_meas, nis, last_update = n_meas + used, filt.nis, t
            elif _lost(filt):
                filt = None
                track.resets += 1
                continue
            if forward is not None:
                forward.node(filt, step)
        if filt is None:
            continue
        if t_k - last_update > p["max_coast_s"]:
            filt = None
            track.resets += 1
            continue
        if forward is not None:       # smoothing: the output time becomes a node of the recorded chain
            if t_k > t_filter and not static[k]:
                forward.node(filt, _predict(filt, motion, t_k - t_filter, None if inputs is None else inputs[k]))
                t_filter = t_k
            forward.output()
        x, P = filt.x[:motion.dim], filt.P[:motion.dim, :motion.dim]      # without calibration states
        if t_k > t_filter and not static[k]:
            F, Q, B = motion.matrices(t_k - t_filter)
            x = F @ x
            u = None if inputs is None else inputs[k]
            if B is not None and u is not None and np.all(np.isfinite(u)):
                x = x + B @ u
            P = F @ P @ F.T + Q
        track.emit(t_k, x, P, n_meas, nis)
    return track.frame()
