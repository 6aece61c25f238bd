"""The estimator registry: every estimator of the project under a config name, with its
parameters (default, unit, meaning) and one entry point.

    estimates = run("ekf", run_data, {"motion": "pva", "anchors": "3: B1,B3,B4"})

returns a DataFrame sorted by time with columns t (s), x, y (m) and, where the estimator
has one, the position covariance p_xx, p_xy, p_yy (m^2); Bayesian filters add n_meas
(measurements in the last update) and nis, and with a 3-D state (`dimensions: 3`) z (m)
and p_zz (m^2). `estimates.attrs` carries counters (resets).
Estimators are compositions of the parts in this package: position solvers and fusions
(fixes), trackers over fixes (trackers), Bayesian filters (bayes, motion, measurements)
and the inertial pipelines (inertial).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
import pandas as pd

from wsnloc.errors import ConfigError, did_you_mean
from wsnloc.estimators import batch, bayes, core, filter_options, fixes, inertial, range_calibration, self_fit, \
    trackers
from wsnloc.estimators.motion import MOTIONS
from wsnloc.estimators.parameters import Param, resolve
from wsnloc.estimators.run_data import RunData
from wsnloc.estimators.measurements import KINDS

# ---- parameter groups ------------------------------------------------------------------
STATIC_START = Param("static_start_s", 4.0, "s", "the mobile rests during the first S s: gravity reference and "
                     "IMU bias measured then (0: none)", minimum=0.0)
COMMON = (
    Param("anchors", "all", "", "anchor subset: 'all', or campaign subset names joined by '+' "
          "(e.g. 'UWB=9+ZigBee=17')", str),
    Param("epoch_s", 0.5, "s", "estimation period T: epochs (t_k - T, t_k]; the output period", minimum=1e-3),
    Param("preliminary_filter", True, "", "drop ranges with a non-zero device status or outside (0, max_range_m]",
          bool),
    Param("max_range_m", 100.0, "m", "longest physically possible range at the site", minimum=0.0),
)
RSS = (
    Param("rss_calibration", "other_run", "", "RSS model from a donor run with truth of the same site (when the "
          "caller has one): 'other_run' = a P0 per receiver and the exponent (the donor's fit or the configured "
          "one) that tracks the donor better, 'other_run_common' = one P0, n, sigma by least squares (the papers'); "
          "'configured' = the values below", str, ("other_run", "other_run_common", "configured")),
    Param("p0_dbm", -60.0, "dBm", "configured RSS at the reference distance d0"),
    Param("path_loss_exponent", 2.0, "1", "configured path-loss exponent n", minimum=0.1),
    Param("sigma_db", 4.0, "dB", "configured shadowing standard deviation", minimum=1e-3),
    Param("d0_m", 1.0, "m", "reference distance of the path-loss model", minimum=1e-3),
)
REFINE = Param("refine", True, "", "multilateration: Gauss-Newton refinement of the closed-form linear least "
               "squares (false: the linear solution alone, paper D's 'simple geometric technique')", bool)
SOLVER = (
    Param("solver", "minmax", "", "position solver", str, fixes.SOLVERS),
    Param("k_smallest", 0, "1", "use only the k smallest distances of an epoch (0: all; paper D: 6)", int, minimum=0),
    REFINE,
    Param("pmix_toa_weight", 0.5, "1", "P-mix: weight w of the range fix (the RSS fix gets 1 - w)", minimum=0.0),
)
VELOCITY = (
    Param("window", 6, "fixes", "speed estimated over the last N fixes (paper D: 6)", int, minimum=1),
    Param("speed_from", "raw", "", "positions feeding the speed window: raw fixes or the tracker's output", str,
          ("raw", "tracked")),
)
KALMAN_FIXES = (
    Param("accel_sigma_mps2", 0.5, "m/s^2", "white acceleration of the PV model"),
    Param("position_sigma_m", 1.5, "m", "fix noise (R = sigma^2 I) and initial position sigma"),
    Param("initial_speed_sigma_mps", 0.5, "m/s", "initial speed sigma"),
    Param("speed_input", False, "", "also update with the velocity algorithm's speed estimate (window, speed_from) "
          "as a measurement of ||v|| (paper D §4.2)", bool),
    Param("speed_sigma_mps", 0.5, "m/s", "speed_input: standard deviation of the speed estimate in R", minimum=1e-6),
)
FILTER = (
    Param("filter", "ekf", "", "Bayesian filter (ukf, pf and filterpy have their own estimators)", str, ("ekf",)),
    Param("measurements", "toa", "", "toa: ranges; rss: RSS; hybrid: both stacked; tdoa: range differences "
          "(tdoa table, correlated noise of pairs sharing an anchor)", str, tuple(KINDS)),
    Param("motion", "pv", "", "p: random walk; pv: constant velocity; pva: measured acceleration input + bias; "
          "odometry: unicycle driven by the run's odometry table (speed, yaw rate; heading in the state)",
          str, MOTIONS),
    Param("dimensions", 2, "1", "position axes of the state: 2 (x, y; the tag at the campaign's fixed "
          "tag_height_m, the default for planar data) or 3 (x, y, z; motion p or pv; needs anchors at varied "
          "heights for z to be observable)", int, minimum=2),
    Param("odometry_speed_sigma_mps", 0.1, "m/s", "odometry: speed error held over a step (wheel odometry: a few "
          "% scale error and slip at speeds up to ~2 m/s)", minimum=1e-6),
    Param("odometry_yaw_rate_sigma_rps", 0.05, "rad/s", "odometry: yaw-rate error held over a step (~3 deg/s: "
          "wheel-base uncertainty and slip of differential-drive odometry)", minimum=1e-6),
    Param("update", "auto", "", "epoch: one update per period; sequential: at each measurement's time; auto: "
          "epoch on synchronous ranging rounds and on RSS alone, sequential on asynchronous ranges (one anchor at a "
          "time, or each anchor at its own time stamp), decided from the run's data (estimators.auto)", str,
          ("auto", "epoch", "sequential")),
    Param("range_sigma_m", 0.3, "m", "range noise standard deviation in R (TDOA: of each anchor's arrival or "
          "range; a pair's difference has sqrt(2) times it)", minimum=1e-6),
    Param("p_sigma_m", 0.5, "m", "P model: position change per period T (0.5: a walk at 1 m/s over the 0.5 s "
          "period; paper C sets its own)", minimum=0.0),
    Param("accel_sigma_mps2", 0.5, "m/s^2", "PV: white acceleration; PVA: acceleration input noise", minimum=0.0),
    Param("bias_walk_sigma", 0.01, "m/s^2/sqrt(s)", "PVA: accelerometer bias random walk", minimum=0.0),
    Param("initial_sigma_m", 1.0, "m", "initial position sigma (around the initiator's fix)", minimum=1e-6),
    Param("initial_speed_sigma_mps", 0.5, "m/s", "initial speed sigma", minimum=1e-6),
    Param("initial_bias_sigma_mps2", 0.05, "m/s^2", "PVA: initial accelerometer bias sigma", minimum=1e-6),
    Param("initial_heading", "fixes", "", "PVA: heading the gyro is integrated from: fixes = measured from the "
          "first multilateration fixes 1 m apart, path = the campaign path's start heading (a known start pose)",
          str, ("fixes", "path")),
    Param("init_window_s", 0.0, "s", "initiator: multilateration on the last W seconds of measurements "
          f"(0: one period, widened up to {bayes.TRACKER_INIT_WINDOW_S:g} s where it holds too few anchors for a "
          "fix)", minimum=0.0),
    Param("max_coast_s", 10.0, "s", "drop the track after this long without an update (sequential: from a second "
          "anchor; one anchor alone gives a distance, not a position); restart by the initiator",
          minimum=0.0),
    Param("max_position_sigma_m", core.MAX_POSITION_SIGMA_M, "m", "do not output an estimate whose position sigma "
          "sqrt(p_xx + p_yy) exceeds this (a track coasting through a gap), nor one beyond max_range_m of every "
          "anchor (counted in attrs `withheld`; 0: output every estimate)", minimum=0.0),
    Param("motion_detection", False, "", "paper A: skip the predict step in epochs the accelerometer finds static",
          bool),
    Param("motion_threshold_mps2", 0.05, "m/s^2", "motion detection: mean | |f| - g | below this is static",
          minimum=0.0),
    STATIC_START,
    Param("range_calibration", "none", "", "correct the ranges before filtering: other_run = scale and per-anchor "
          "offsets fitted on a donor run with truth of the same dataset (configured values without one), "
          "configured = the campaign file's range_calibration, none = as measured", str, range_calibration.SOURCES),
    Param("self_fit", "none", "", "two_pass: fit the range scale and per-anchor offsets against the track (kept when "
          "a likelihood-ratio test supports them) and the range and process noise by maximum likelihood of the "
          "innovations, then run with them (offline, no truth; under 3x one pass; estimators.self_fit); none: the "
          "configured values", str, self_fit.MODES),
) + filter_options.PARAMS
SLIDING_WINDOW = (
    Param("measurements", "toa", "", "toa: ranges; tdoa: range differences (tdoa table, each time group whitened "
          "by its correlated noise)", str, ("toa", "tdoa")),
    Param("range_sigma_m", 0.3, "m", "range noise standard deviation (residuals are whitened by it; TDOA: of "
          "each anchor's arrival)", minimum=1e-6),
    Param("window_s", 2.0, "s", "window W: ranges of the last W seconds are solved jointly (4 rounds at 2 Hz; "
          "cost and latency grow with W)", minimum=1e-3),
    Param("knot_s", 0.5, "s", "spacing of the constant-velocity knots (one per 2 Hz round); at most window_s",
          minimum=1e-3),
    Param("accel_sigma_mps2", 0.5, "m/s^2/sqrt(Hz)", "constant-velocity prior between knots: white acceleration "
          "of spectral density sigma^2 (m^2/s^3)", minimum=1e-6),
    Param("loss", "huber", "", "robust loss on the range residuals (scipy.optimize.least_squares's losses)", str,
          ("huber", "soft_l1", "cauchy", "linear")),
    Param("f_scale", 1.345, "sigma", "where the robust loss turns from quadratic, in units of range_sigma_m "
          "(1.345: Huber's 95% efficiency under Gaussian noise)", minimum=1e-6),
    Param("prior_inflation", 10.0, "1", "the previous window's solution enters as a prior with its covariance "
          "times this (its overlapping ranges are not counted twice at full weight)", minimum=1e-6),
    Param("max_coast_s", 10.0, "s", "drop the solution after this long without a range; restart by "
          "multilateration on a window", minimum=0.0),
)
INERTIAL = (
    STATIC_START,
    Param("process_sigma_m", 0.05, "m", "dead-reckoning displacement error per 5 Hz step", minimum=1e-6),
    Param("fix_sigma_m", 1.0, "m", "fix error (R = sigma^2 I)", minimum=1e-6),
)


def _with(params: tuple[Param, ...], **defaults) -> tuple[Param, ...]:
    """The parameter group with other defaults (a preset)."""
    unknown = set(defaults) - {p.name for p in params}
    assert not unknown, unknown
    return tuple(replace(p, default=defaults[p.name]) if p.name in defaults else p for p in params)


def _drop(params: tuple[Param, ...], *names: str) -> tuple[Param, ...]:
    return tuple(p for p in params if p.name not in names)


def _filter(params: tuple[Param, ...], *filters: str) -> tuple[Param, ...]:
    """The parameter group with `filter` restricted to the given filters (the first is the default)."""
    return tuple(replace(p, default=filters[0], choices=filters) if p.name == "filter" else p for p in params)


# ---- estimator entries --------------------------------------------------------------------
@dataclass(frozen=True)
class Estimator:
    name: str
    summary: str
    params: tuple[Param, ...]
    function: Callable[[RunData, dict], pd.DataFrame]
    inputs: Callable[[dict], tuple[str, ...]] = field(default=lambda p: ())   # extra tables: imu, imu_5hz

    def resolve(self, overrides: dict, where: str = "") -> dict:
        return resolve(self.params, overrides, where or f"estimator {self.name}")

    def tables(self, p: dict) -> tuple[str, ...]:
        """The processed tables this estimator reads with parameters p."""
        return ("ranges", "rss", "truth", "anchors") + (("tdoa",) if p.get("measurements") == "tdoa" else ()) \
            + self.inputs(p)

    @property
    def reads_tdoa(self) -> bool:
        """Whether the estimator accepts range differences (`measurements: tdoa`)."""
        return any(p.name == "measurements" and "tdoa" in (p.choices or ()) for p in self.params)

    def describe(self) -> dict:
        return {"name": self.name, "summary": self.summary, "tdoa": self.reads_tdoa,
                "parameters": [p.describe() for p in self.params]}


def _solver_run(solver: str | None, technique: str | None):
    def run(data: RunData, p: dict) -> pd.DataFrame:
        q = dict(p, solver=solver or p["solver"])
        return fixes.epoch_fixes(data, q, technique or p["measurements"])
    return run


def _velocity_run(data: RunData, p: dict) -> pd.DataFrame:
    return trackers.run_velocity_track(data, p)


def _kalman_run(data: RunData, p: dict) -> pd.DataFrame:
    return trackers.kalman_tracks([data], [p])[0].frame()


def _minmax_fixes(p: dict) -> dict:
    """The Min-Max fixes the inertial pipelines fuse (paper B: Min-Max on the ranges)."""
    return dict(p, solver="minmax")


def _dead_reckoning_run(data: RunData, p: dict) -> pd.DataFrame:
    return inertial.dead_reckoning(data, p["static_start_s"])[["t", "x", "y"]]


def _fused_run(steady_state: bool):
    def run(data: RunData, p: dict) -> pd.DataFrame:
        return inertial.fused(data, fixes.epoch_fixes(data, _minmax_fixes(p), "toa"), p, steady_state)
    return run


def _filter_inputs(p: dict) -> tuple[str, ...]:
    return (("imu",) if p["motion_detection"] else ()) + (("imu_5hz",) if p["motion"] == "pva" else ()) \
        + (("odometry",) if p["motion"] == "odometry" else ())


K_SMALLEST = _drop(SOLVER, "solver", "pmix_toa_weight", "refine")
SOLVER_MEASUREMENTS = K_SMALLEST + (Param("measurements", "toa", "", "toa: ranges; rss: RSS distances", str,
                                          ("toa", "rss")),)
FIX_SOURCE = COMMON + RSS + SOLVER + (Param("fixes", "toa", "", "fixes tracked: toa, rss, pmix or fmix", str,
                                            fixes.TECHNIQUES),)
TRACKER_DEFAULTS = dict(update="sequential", init_window_s=bayes.TRACKER_INIT_WINDOW_S, initial_sigma_m=2.0,
                        gate_probability=filter_options.STANDARD_GATE, self_fit="two_pass")
# The general filters and smoothers self-fit as the tracker does (the same noise and range errors
# of the run; without it they fall 1.6-2.4x behind it on real ranges, benchmarks/ASYNC_RESULTS.md);
# the Kalman filters also gate as it does: real ranges carry NLOS outliers. The particle filter
# has a heavy-tailed likelihood instead of a gate.
SELF_FITTED_FILTER = _with(FILTER, self_fit=TRACKER_DEFAULTS["self_fit"])
GATED_FILTER = _with(SELF_FITTED_FILTER, gate_probability=TRACKER_DEFAULTS["gate_probability"])
# The smoothers do not re-fix by default: their backward pass carries the run across a forward
# transient and a restart splits the chain; measured mixed (docs/realdata.md: RMSE lower on 16 of
# 25 simulated one-anchor-at-a-time walks, higher on 7, 3x on 3 of the simulated Cricket runs).
GATED_SMOOTHER = _with(GATED_FILTER, gate_refix=False)

ESTIMATORS: dict[str, Estimator] = {e.name: e for e in [
    Estimator("minmax", "Min-Max: centre of the intersection of the range boxes, per epoch (paper D)",
              COMMON + RSS + SOLVER_MEASUREMENTS, _solver_run("minmax", None)),
    Estimator("multilateration", "Linearised least squares (+ Gauss-Newton with refine) on the ranges, per epoch "
              "(paper D)", COMMON + RSS + SOLVER_MEASUREMENTS + (REFINE,),
              _solver_run("multilateration", None)),
    Estimator("pmix", "P-mix: weighted barycentre of the range fix and the RSS fix (paper D)",
              COMMON + RSS + SOLVER, _solver_run(None, "pmix")),
    Estimator("fmix", "F-mix: one solver on ranges and RSS distances together (paper D)",
              COMMON + RSS + SOLVER, _solver_run(None, "fmix")),
    Estimator("velocity_tracker", "Velocity-bounded tracker over per-epoch fixes (paper D)",
              FIX_SOURCE + VELOCITY, _velocity_run),
    Estimator("kf_tracker", "Constant-velocity Kalman filter over per-epoch fixes (paper D's comparison)",
              FIX_SOURCE + KALMAN_FIXES + VELOCITY, _kalman_run),
    Estimator("ekf", "EKF: motion model p / pv / pva, toa / rss / hybrid measurements, epoch or sequential "
              f"updates, optional motion detection, innovation gate at {filter_options.STANDARD_GATE} "
              "(papers A and C: their cells have no gate)",
              COMMON + RSS + GATED_FILTER, bayes.run_filter, _filter_inputs),
    Estimator("ekf_p", f"EKF with the P (random walk) model (paper C), gated at {filter_options.STANDARD_GATE} and "
              "self-fitted as the "
              "tracker (its random walk's p_sigma_m is a speed, which differs from run to run)",
              COMMON + RSS + _with(GATED_FILTER, motion="p"),
              bayes.run_filter, _filter_inputs),
    Estimator("ekf_pva", "EKF with the PVA model: measured acceleration as input, bias states (paper C)",
              COMMON + RSS + _with(FILTER, motion="pva"), bayes.run_filter, _filter_inputs),
    Estimator("ekf_motion_detection", "PV EKF that skips the prediction while the accelerometer says static "
              "(paper A, Table II)", COMMON + RSS + _with(FILTER, motion_detection=True),
              bayes.run_filter, _filter_inputs),
    Estimator("tracker", "Recommended tracker for any range data: PV EKF with sequential updates (ranges used "
              f"at their own times, one anchor at a time is fine), innovation gate at {filter_options.STANDARD_GATE}, window initiator, "
              "coasting limit",
              COMMON + RSS + _with(FILTER, **TRACKER_DEFAULTS), bayes.run_filter, _filter_inputs),
    Estimator("ukf", "Unscented Kalman filter (scaled sigma points) with the EKF's motion models, measurements, "
              "update modes, gate, initiator and coasting limit", COMMON + RSS + _filter(GATED_FILTER, "ukf") + bayes.UKF,
              bayes.run_filter, _filter_inputs),
    Estimator("pf", "Bootstrap particle filter (systematic resampling on ESS with a shrunk kernel, heavy-tailed "
              "range likelihood, restart from a fix when its likelihood collapses) with the EKF's motion models, "
              "measurements, update modes, initiator and coasting limit",
              COMMON + RSS + _filter(SELF_FITTED_FILTER, "pf") + bayes.PARTICLE, bayes.run_filter, _filter_inputs),
    Estimator("ekf_filterpy", "filterpy's EKF (the textbook reference) in the same loops, initiator, coasting "
              "limit and update options as ekf: its estimates equal ekf's to round-off",
              COMMON + RSS + _filter(GATED_FILTER, "filterpy"), bayes.run_filter, _filter_inputs),
    Estimator("ekf_rts", "EKF followed by the fixed-interval RTS smoother (offline: each estimate uses the "
              "whole run)", COMMON + RSS + GATED_SMOOTHER, bayes.run_smoother, _filter_inputs),
    Estimator("ukf_rts", "UKF followed by the fixed-interval RTS smoother (offline: each estimate uses the "
              "whole run)", COMMON + RSS + _filter(GATED_SMOOTHER, "ukf") + bayes.UKF, bayes.run_smoother,
              _filter_inputs),
    Estimator("sliding_window", "Sliding-window batch: robust non-linear least squares over the ranges of the "
              "last W seconds with a constant-velocity prior (factor-graph style)",
              COMMON + SLIDING_WINDOW, batch.sliding_window),
    Estimator("dead_reckoning", "Dead reckoning of the 5 Hz IMU from the start pose (paper B)",
              _drop(INERTIAL, "process_sigma_m", "fix_sigma_m"), _dead_reckoning_run, lambda p: ("imu_5hz",)),
    Estimator("dr_sskf", "Dead reckoning fused with Min-Max fixes by a steady-state KF (paper B)",
              COMMON + K_SMALLEST + INERTIAL, _fused_run(True),
              lambda p: ("imu_5hz",)),
    Estimator("dr_kf", "Dead reckoning fused with Min-Max fixes by the classical KF (paper B)",
              COMMON + K_SMALLEST + INERTIAL, _fused_run(False),
              lambda p: ("imu_5hz",)),
]}

DEFAULT_ESTIMATOR = "tracker"


def get(name: str, where: str = "estimator") -> Estimator:
    if name not in ESTIMATORS:
        raise ConfigError(f"config key '{where}': unknown estimator {name!r}{did_you_mean(name, ESTIMATORS)} "
                          f"(registered: {', '.join(ESTIMATORS)})")
    return ESTIMATORS[name]


def run(name: str, data: RunData, overrides: dict | None = None, where: str = "") -> pd.DataFrame:
    """Resolve the parameters and run one estimator on one run (see the module docstring)."""
    estimator = get(name)
    p = estimator.resolve(overrides or {}, where)
    return finish(estimator.function(data, p))


def finish(estimates: pd.DataFrame) -> pd.DataFrame:
    """Standard columns (NaN covariance, n_meas and nis where the estimator has none), sorted by
    time. A shallow copy: estimators may return frames they cache for other estimators."""
    missing = [column for column in core.COLUMNS if column not in estimates]
    columns = {name: (values.astype(float) if name in core.COLUMNS and values.dtype != float else values).array
               for name, values in estimates.items()}
    out = pd.DataFrame({**columns, **{column: np.full(len(estimates), np.nan) for column in missing}},
                       index=estimates.index, copy=False)
    out.attrs = dict(estimates.attrs)
    if not out["t"].is_monotonic_increasing:
        out = out.sort_values("t", kind="stable")
    return out.reset_index(drop=True)
