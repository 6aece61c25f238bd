"""Bayesian filters assembled from parts: motion model, measurement models, update mode,
initiator, coasting limit and optional motion detection (papers A and C, and any dataset).
The loops and their components (initiator, deleter, filter banks) are in estimators.core.

Update modes (core.epoch_loop, core.sequential_loop)
- `epoch`: one predict (step T) and one update per estimation period with the epoch's
  measurements (per-anchor means), as in papers A and C; output at every epoch end t_k.
- `sequential`: the filter predicts to each measurement's own time and updates with it
  (records sharing a time stamp update together), so ranges that arrive one anchor at a
  time are used as they come; output at the same epoch ends t_k, predicted from the
  last update (not stored). When every measurement of an epoch carries the time t_k,
  both modes give the same estimates.
- `auto` (the default of every filter but `tracker`): `epoch` on synchronous ranging rounds
  and RSS alone, `sequential` on asynchronous ranges, decided per run (resolve_update,
  estimators.auto.update_mode); attrs `update` says which.
Numerical guards (filters.numerics): per run, the covariances regularised, updates skipped
  and particle-filter restarts, in attrs `regularised`, `skipped`, `reinitialised`.
Initiator (core.WindowInitiator, `init_window_s`): the first time the measurements of the
  last `init_window_s` seconds (per-anchor means) give a multilateration fix, the state
  starts there (speed and bias 0, P0). 0 (the default but for `tracker`): one period, doubled
  up to TRACKER_INIT_WINDOW_S where that holds too few anchors (ranges one anchor at a time).
Deleter (core.CoastingDeleter, `max_coast_s`): after `max_coast_s` seconds without an update
  (sequential mode: from a second anchor, core.Support; one anchor alone gives a distance, not a
  position), or when the innovation gate finds the track lost (estimators.filter_options), the track is
  dropped (counted as a reset) and restarted by the initiator; no estimate is output
  meanwhile, so a long gap shows as lower availability instead of unbounded drift. Before that,
  an estimate whose position sigma passes `max_position_sigma_m`, or that lies beyond `max_range_m`
  of every anchor, is not output
  (core.withhold_uncertain; the smoothers' on their smoothed covariance), counted in attrs `withheld`.
Motion detection (paper A): in epochs declared static by the accelerometer the predict
  step is skipped (state and covariance frozen).
Filters (`FILTERS`, parameter `filter`): `ekf` (filters.kalman), `ukf` (scaled sigma points,
  filters.ukf: alpha, beta, kappa) and `pf` (bootstrap particle filter, filters.particle:
  n_particles, resample_threshold, outlier_probability, outlier_span_m, seed) and `filterpy`
  (filterpy's EKF as the textbook reference, filters.reference); all share the
  predict(F, Q, u, B) / update_model(model) interface, so both loops run any of them
  (core.FilterBank). The bare epoch-mode EKF runs as array_ekf.ArrayEKF instead (the same
  filter for many runs at once; `run_filters` steps every cell sharing a motion model,
  period, initiator and deleter together).
  The particle filter draws from one numpy Generator per run, seeded with
  (seed, CRC-32 of the run's measurements): reproducible, and independent between runs.
Smoothing (`run_smoother`): the forward pass is recorded (smoothing.ForwardPass) and the
  fixed-interval RTS smoother runs over each track segment offline; see smoothing.py.
"""

from __future__ import annotations

import zlib

import numpy as np
import pandas as pd

from wsnloc.errors import ConfigError
from wsnloc.estimators import array_ekf, range_calibration, self_fit
from wsnloc.estimators.auto import update_mode
from wsnloc.estimators.core import COLUMNS_3D, CoastingDeleter, FilterBank, RunInputs, Track, WindowInitiator, \
    epoch_loop, sequential_loop, withhold_uncertain
from wsnloc.estimators.filter_options import STANDARD_GATE, UpdateCounts, configured_factory, site_bounds
from wsnloc.estimators.fixes import epoch_fixes
from wsnloc.estimators.inertial import epoch_inputs, floor_input, heading_from_fixes
from wsnloc.estimators.measurements import MeasurementSource, rss_params
from wsnloc.estimators.motion import MotionModel
from wsnloc.estimators.parameters import Param
from wsnloc.estimators.run_data import RunData
from wsnloc.estimators.smoothing import ForwardPass
from wsnloc.estimators.tdoa import TdoaSource
from wsnloc.filters.kalman import ExtendedKalmanFilter
from wsnloc.filters.numerics import Guards
from wsnloc.filters.particle import ParticleFilter
from wsnloc.filters.reference import FilterpyEKF
from wsnloc.filters.ukf import UnscentedKalmanFilter
from wsnloc.inertial.motion_detection import static_epochs

ODOMETRY_INPUTS = ("v_mps", "yaw_rate_rps")     # the odometry table's columns, the odometry model's u


# The parameters only the UKF and the particle filter read (registry: their estimators add them).
UKF = (
    Param("alpha", 1.0, "1", "UKF sigma-point spread; 1 with kappa = 0 gives lambda = 0: non-negative weights, "
          "S and P stay positive semi-definite (a small alpha such as 1e-3 amplifies round-off)", minimum=1e-6),
    Param("beta", 2.0, "1", "UKF prior-distribution term of the centre weight Wc_0; 2 is optimal for a Gaussian "
          "prior"),
    Param("kappa", 0.0, "1", "UKF secondary scaling, lambda = alpha^2 (n + kappa) - n"),
)
PARTICLE = (
    Param("n_particles", 1000, "1", "particle filter size N: Monte Carlo error of the mean ~ spread / sqrt(N), "
          "a few cm for a 1 m posterior spread at 1000; cost grows linearly", int, minimum=1),
    Param("resample_threshold", 0.5, "1", "systematic resampling when the effective sample size 1 / sum w^2 "
          "falls below this share of N (0..1; the usual N/2 rule)", minimum=0.0),
    Param("outlier_probability", 0.05, "1", "heavy-tailed range likelihood (1 - eps) N(r; 0, sigma^2) + eps / span "
          "(0..1; 0: Gaussian, the EKF's likelihood; 0.05: real UWB, where NLOS and multipath give a few ranges "
          "metres long, which a Gaussian likelihood lets drag the cloud)", minimum=0.0),
    Param("outlier_span_m", 50.0, "m", "span of the uniform outlier component: the longest range error "
          "possible (site diagonal plus the largest NLOS excess)", minimum=1e-3),
    Param("seed", 0, "1", "random stream of each run: numpy Generator seeded with (seed, CRC-32 of the run's "
          "measurements), so results are reproducible and runs independent", int, minimum=0),
)
FILTER_OWN_PARAMS = frozenset(p.name for p in UKF + PARTICLE)


def ekf_factory(p: dict, data: RunData, guards: Guards):
    def make(x0: np.ndarray, P0: np.ndarray, motion: MotionModel):
        F, Q, _ = motion.matrices(motion.period_s)
        return ExtendedKalmanFilter(x0, P0, F, Q, guards)
    return make


def ukf_factory(p: dict, data: RunData, guards: Guards):
    def make(x0: np.ndarray, P0: np.ndarray, motion: MotionModel):
        return UnscentedKalmanFilter(x0, P0, p["alpha"], p["beta"], p["kappa"], guards)
    return make


def run_generator(seed: int, data: RunData) -> np.random.Generator:
    """The random stream of one run: numpy Generator seeded with (seed, CRC-32 of the run's
    measurements): the same measurements give the same estimates whatever the run is called or
    where it lies (seeded by the run's name, byte-identical copies of a TDOA run in four folders
    gave a particle filter RMSE of 42-124 m), and different runs draw different streams."""
    return np.random.default_rng([seed, data.cached(("measurement crc",), lambda: _measurement_crc(data))])


def _measurement_crc(data: RunData) -> int:
    """CRC-32 of the run's measurement tables (ranges, RSS, range differences: every column but
    the raw file's line numbers), through pandas' row hashes, sorted: the same rows in any order
    in the file give the same stream."""
    crc = 0
    for name in ("ranges", "rss", "tdoa"):
        frame = data.table(name)
        if len(frame):
            rows = pd.util.hash_pandas_object(frame.drop(columns=["line"], errors="ignore"), index=False)
            crc = zlib.crc32(np.sort(rows.to_numpy()).tobytes(), crc)      # sorted: rows of one time stamp in any order
    return crc


def pf_factory(p: dict, data: RunData, guards: Guards):
    rng = run_generator(p["seed"], data)           # one stream per run: a restarted track continues it

    def make(x0: np.ndarray, P0: np.ndarray, motion: MotionModel):
        return ParticleFilter(x0, P0, p["n_particles"], rng, p["resample_threshold"], p["outlier_probability"],
                              p["outlier_span_m"], guards)
    return make


def filterpy_factory(p: dict, data: RunData, guards: Guards):
    def make(x0: np.ndarray, P0: np.ndarray, motion: MotionModel):
        return FilterpyEKF(x0, P0)
    return make


# filter name -> factory(parameters, run, guards) -> make(x0, P0, motion) -> a filter with x, P, nis,
# predict(F, Q, u, B) and update_model(model); guards (filters.numerics): the run's counters of
# regularised covariances, skipped updates and particle-filter restarts
FILTERS = {"ekf": ekf_factory, "ukf": ukf_factory, "pf": pf_factory, "filterpy": filterpy_factory}


def motion_model(p: dict) -> MotionModel:
    """The motion model of parameters p; ConfigError for a state it has not (3-D PVA or odometry)."""
    try:
        return MotionModel(p["motion"], p["epoch_s"], p["p_sigma_m"], p["accel_sigma_mps2"], p["bias_walk_sigma"],
                           p["initial_sigma_m"], p["initial_speed_sigma_mps"], p["initial_bias_sigma_mps2"],
                           p.get("dimensions", 2), p.get("odometry_speed_sigma_mps", 0.0),
                           p.get("odometry_yaw_rate_sigma_rps", 0.0))
    except ValueError as exc:
        raise ConfigError(f"config keys 'motion' / 'dimensions': {exc}") from None


def measurement_source(data: RunData, p: dict) -> MeasurementSource:
    """The measurements (and their models) a filter with parameters p reads from the run, the
    ranges (or TDOA, `measurements: tdoa`, through estimators.tdoa.TdoaSource) corrected by the
    configured range calibration (range_calibration.correction)."""
    if p["measurements"] == "tdoa":
        args = (p["anchors"], p["range_sigma_m"], p["max_range_m"], range_calibration.correction(data, p),
                p.get("dimensions", 2))
        return data.cached(("tdoa_source",) + args, lambda: TdoaSource(data, *args))
    args = (p["measurements"], p["anchors"], p["range_sigma_m"], p["preliminary_filter"], p["max_range_m"],
            rss_params(data, p) if p["measurements"] != "toa" else None, range_calibration.correction(data, p),
            p.get("dimensions", 2))
    return data.cached(("measurement_source",) + args, lambda: MeasurementSource(data, *args))


def static_flags(data: RunData, p: dict, times: np.ndarray) -> np.ndarray:
    """Per epoch ending at times: True where motion detection (if enabled) skips the predict
    step; computed once per run and setting (the rows of a paper share it)."""
    if not p["motion_detection"]:
        return np.zeros(len(times), dtype=bool)
    return data.cached(("static_epochs", p["epoch_s"], p["motion_threshold_mps2"], p["static_start_s"], len(times)),
                       lambda: static_epochs(data.require("imu", "motion detection"), times, p["epoch_s"],
                                             p["motion_threshold_mps2"], p["static_start_s"]))


def pva_heading(data: RunData, p: dict) -> float | None:
    """Start heading (rad) of the PVA input's gyro integration: None (the campaign path's, a known
    start pose) for initial_heading 'path'; for 'fixes' measured from the run's first
    multilateration fixes (inertial.heading_from_fixes), the path's when they never move 1 m."""
    if p["initial_heading"] == "path":
        return None
    fixes = epoch_fixes(data, dict(p, solver="multilateration", k_smallest=0, refine=True), "toa")
    return heading_from_fixes(fixes)


def run_inputs(data: RunData, p: dict, motion: MotionModel) -> RunInputs:
    """What a filter with parameters p reads from the run: measurement source, epoch end
    times, static flags and inputs per epoch (PVA: mean floor acceleration; odometry: mean
    speed and yaw rate; None without)."""
    source = measurement_source(data, p)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    inputs = None
    if motion.kind == "pva":
        inputs = epoch_inputs(floor_input(data, p["static_start_s"], pva_heading(data, p)), times)
    elif motion.kind == "odometry":
        inputs = epoch_inputs(data.require("odometry", "the odometry motion model"), times, ODOMETRY_INPUTS)
    return RunInputs(times, source, static_flags(data, p, times), inputs)


def run_filter(data: RunData, p: dict) -> pd.DataFrame:
    """Estimates (core.COLUMNS) of one run; `attrs`: resets (coasting-limit resets), gated / offered
    measurements and gated_share (filter_options), the self-calibration states range_scale /
    range_offset_m, and the range calibration applied (range_calibration.RangeCorrection.describe).
    With self_fit=two_pass on a run with ranges: the self-fitted estimates (estimators.self_fit)."""
    if self_fitted(p):
        return self_fit.two_pass(data, p, _fit_pass, _plain_filter)
    return _plain_filter(data, p)


def _plain_filter(data: RunData, p: dict) -> pd.DataFrame:
    return run_filters([(data, p)])[0].frame()


def self_fitted(p: dict) -> bool:
    """Whether parameters p ask for the self-fit (estimators.self_fit): a filter reading ranges."""
    return p.get("self_fit", "none") != "none" and p["measurements"] != "rss"


def _fit_pass(data: RunData, p: dict) -> tuple[pd.DataFrame, tuple[np.ndarray, np.ndarray]]:
    """One gated EKF pass of run_filter (no self-fit) and the innovations (y, S_ii) it recorded:
    the self-fit's passes of every filter and smoother, which then run once with the fitted
    values (the noise and range errors are the run's, whichever filter reads them; a particle
    filter per candidate would cost several times its own pass). Gated at the filter's gate,
    or at STANDARD_GATE for an ungated filter (the particle filter has no gate): ungated, NLOS
    ranges pull the fit's track and the range correction read from it (on the real outdoor UWB
    runs it then applied a correction the gated fit rejects and doubled the pf's median).

    The pass depends on the run, its range correction and the EKF's parameters only, so it is
    computed once per run and key (RunData.cached): the cells of a study that differ in the filter
    or in the UKF's and particle filter's own parameters share their fit passes."""
    q = dict(p, self_fit="none", filter="ekf", gate_probability=p["gate_probability"] or STANDARD_GATE)

    def build():
        counts: list[UpdateCounts] = []
        frame = run_filters([(data, q)], counts_out=counts)[0].frame()
        return frame, counts[0].innovation_arrays()
    key = tuple(sorted((k, v) for k, v in q.items() if k not in FILTER_OWN_PARAMS))
    return data.cached(("fit_pass", range_calibration.model_key(data.range_model), key), build)


def run_smoother(data: RunData, p: dict) -> pd.DataFrame:
    """The fixed-interval RTS-smoothed estimates of one run (same rows as the forward pass;
    n_meas and nis are the forward pass's). In sequential mode the recorded forward pass
    steps the filter to every output time (see smoothing.py). With self_fit=two_pass: smoothed
    with the self-fitted values (the fit's passes are EKF filter passes, _fit_pass)."""
    if p.get("range_self_calibration", "none") != "none":
        raise ConfigError("range_self_calibration: the RTS smoothers do not smooth the calibration states; "
                          "use range_calibration (donor or configured) or self_fit with a smoother")
    if self_fitted(p):
        return self_fit.two_pass(data, p, _fit_pass, _plain_smoother)
    return _plain_smoother(data, p)


def _plain_smoother(data: RunData, p: dict) -> pd.DataFrame:
    forward = ForwardPass()
    track = run_filters([(data, p)], forward)[0]
    rows = track.rows.copy()
    if len(rows):
        smoothed = forward.smooth()
        xs = np.array([x for x, _ in smoothed])
        Ps = np.array([P for _, P in smoothed])
        rows[:, 1:3], rows[:, 3:6] = xs[:, :2], Ps[:, [0, 0, 1], [0, 1, 1]]
        if track.columns == COLUMNS_3D:
            rows[:, -2], rows[:, -1] = xs[:, 2], Ps[:, 2, 2]
    rows, withheld = withhold_uncertain(rows, p["max_position_sigma_m"], data.subset_positions(p["anchors"]),
                                        p["max_range_m"])
    return Track(rows, dict(track.attrs, withheld=withheld)).frame()


# s: the tracker's initiator window, and the widest the other filters' (one period) is widened to:
# ranges one anchor at a time at 2-4 Hz from 4-5 anchors hold three anchors within it
TRACKER_INIT_WINDOW_S = 4.0

# groups of fewer bare-EKF cells run as filter objects: the array EKF's packing and array
# overhead cost more than it saves below about 3 cells (benchmarks/run.py, "filter bank" rows)
ARRAY_MIN_CELLS = 3


def components(p: dict) -> tuple[WindowInitiator, CoastingDeleter]:
    """The initiator and the deleter of parameters p: init_window_s 0 starts from one period,
    widened up to the tracker's window where that holds no fix (WindowInitiator)."""
    window = WindowInitiator(p["init_window_s"]) if p["init_window_s"] \
        else WindowInitiator(p["epoch_s"], TRACKER_INIT_WINDOW_S)
    return window, CoastingDeleter(p["max_coast_s"])


def resolve_update(data: RunData, p: dict) -> dict:
    """p with `update: auto` replaced by the mode the run's ranges call for (auto.update_mode:
    epoch on synchronous rounds and on RSS alone, else sequential); other modes unchanged."""
    if p["update"] != "auto":
        return p
    records = measurement_source(data, p).records()
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    ranges = records.kind == 0
    mode, _ = data.cached(("update_mode", p["epoch_s"], p["anchors"], p["measurements"], p["preliminary_filter"],
                           p["max_range_m"]),
                          lambda: update_mode(records.t[ranges], records.anchor[ranges], times, p["epoch_s"]))
    return dict(p, update=mode)


def run_filters(cells: list[tuple[RunData, dict]], forward: ForwardPass | None = None,
                counts_out: list | None = None) -> list[Track]:
    """run_filter of every (run, resolved parameters) cell, as Tracks. Epoch-mode cells sharing
    a motion model, period, initiator, deleter and bank kind run through one core.epoch_loop
    (the bare EKF of ARRAY_MIN_CELLS cells or more as array_ekf.ArrayEKF, other filters and
    smaller groups as a core.FilterBank, the same numbers to round-off); sequential cells
    through core.sequential_loop one at a time (`update: auto` resolved per run: resolve_update).
    forward (smoothing): one cell. attrs `update`: the mode used. counts_out: a list that receives
    each cell's filter_options.UpdateCounts (innovations), in cell order."""
    cells = [(data, resolve_update(data, p)) for data, p in cells]
    groups: dict[tuple, list[int]] = {}
    for i, (_, p) in enumerate(cells):
        if p["update"] == "epoch":
            bare = forward is None and array_ekf.supports(p)
            groups.setdefault((bare, motion_model(p), p["epoch_s"], components(p)), []).append(i)
        else:
            groups[("sequential", i)] = [i]
    tracks: list[Track | None] = [None] * len(cells)
    all_counts: list = [None] * len(cells)
    for key, members in groups.items():
        p = cells[members[0]][1]
        motion, (initiator, deleter) = motion_model(p), components(p)
        runs = [run_inputs(data, q, motion) for data, q in (cells[i] for i in members)]
        counts = [UpdateCounts() for _ in members]
        guards = [Guards() for _ in members]
        bounds = [site_bounds(data.subset_positions(q["anchors"]), q) for data, q in (cells[i] for i in members)]
        makes = [configured_factory(FILTERS[q["filter"]](q, data, g), q, c, data.campaign, bounds=b)
                 for (data, q), c, g, b in zip((cells[i] for i in members), counts, guards, bounds)]
        if key[0] == "sequential":
            out = [sequential_loop(makes[0], runs[0], motion, initiator, deleter, forward)]
        else:
            bank = array_ekf.ArrayEKF(runs, p["epoch_s"], motion.dim, bounds, guards) \
                if key[0] and len(runs) >= ARRAY_MIN_CELLS \
                else FilterBank(makes, [r.source.epoch_models(r.times, p["epoch_s"]) for r in runs])
            out = epoch_loop(bank, runs, motion, p["epoch_s"], initiator, deleter, forward)
        for i, run, c, g, (rows, resets) in zip(members, runs, counts, guards, out):
            cell, q = cells[i]
            rows, withheld = (rows, 0) if forward is not None \
                else withhold_uncertain(rows, q["max_position_sigma_m"], cell.subset_positions(q["anchors"]),
                                        q["max_range_m"])
            # (the smoothers withhold on the smoothed covariance: _plain_smoother)
            tracks[i] = Track(rows, {"resets": resets, "withheld": withheld, "update": q["update"],
                                     **c.attrs(), **g.attrs(), **run.source.correction.describe()})
            all_counts[i] = c
    if counts_out is not None:
        counts_out.extend(all_counts)
    return tracks
