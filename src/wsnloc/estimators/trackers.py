"""Trackers over a sequence of fixes (paper D): the velocity-bounded tracker and a
constant-velocity Kalman filter with the fixes as position measurements.

KF (`kf_tracker`): the filter core's epoch loop (core.epoch_loop) with the PV motion model
(state [x, y, vx, vy], white acceleration sigma_a over the epoch T), an initiator that starts
at the first fix (FixInitiator: x0 = [fix, 0, 0], P0 = diag(sigma_fix^2, sigma_fix^2,
sigma_v^2, sigma_v^2)), no coasting limit, and a bank (FixBank) of the runs' filters as arrays
whose measurement is the fix, z = [x, y] = H x + v, R = sigma_fix^2 I. It predicts at every
epoch after the start (with or without a fix) and is updated with each fix; a single run is
a batch of one. Both trackers output only at epochs that have a fix.

Fed the velocity algorithm's speed (`speed_input`; paper D §4.2: "z_k is populated with the
position estimates coming from Min-Max ... while the velocity algorithm provides speed
estimates"): the velocity tracker's window speed v_hat (eq. 1) at the fix joins the update as a
third component, z = [x, y, v_hat], h(x) = [x, y, ||v||], H_3 = [0, 0, vx / ||v||, vy / ||v||],
R_33 = sigma_v^2 (an EKF update); position-only where v_hat is undefined (window not filled) or
the predicted ||v|| < MIN_SPEED_MPS (no direction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc.estimators import core, fixes
from wsnloc.estimators.motion import MotionModel
from wsnloc.estimators.run_data import RunData
from wsnloc.filters.kalman import joseph_update, nis, predict
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker

MIN_SPEED_MPS = 1e-3     # below this predicted speed ||v|| has no direction: the speed component is left out


def fix_motion(epoch_s: float, accel_sigma_mps2: float, position_sigma_m: float,
               initial_speed_sigma_mps: float) -> MotionModel:
    """The KF's motion model: PV (estimators.motion, filters.motion_models.constant_velocity) with
    P0 = diag(sigma_fix^2, sigma_fix^2, sigma_v^2, sigma_v^2)."""
    return MotionModel("pv", epoch_s, 0.0, accel_sigma_mps2, 0.0, position_sigma_m, initial_speed_sigma_mps, 0.0)


def fix_measurement(position_sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(H, R) of a fix as the KF's measurement: z = [x, y] = H x + v, R = sigma_fix^2 I."""
    return np.hstack([np.eye(2), np.zeros((2, 2))]), np.eye(2) * position_sigma_m**2


def velocity_pass(t: np.ndarray, xy: np.ndarray, window: int, speed_from: str) -> tuple[np.ndarray, np.ndarray]:
    """The velocity-bounded tracker over per-epoch fixes t (s), xy (m; NaN rows: no fix): per
    epoch its tracked position (m; NaN without a fix) and its speed v_hat (m/s) after the fix
    (NaN: none yet); the epochs without a fix are skipped."""
    tracker = VelocityBoundedTracker(window, speed_from)
    tracked, speed = np.full(xy.shape, np.nan), np.full(len(t), np.nan)
    for k in np.flatnonzero(np.isfinite(xy).all(axis=1)):
        tracked[k] = tracker.update(float(t[k]), float(xy[k, 0]), float(xy[k, 1]))
        speed[k] = tracker.speed
    return tracked, speed


def _table_arrays(fixes: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    return fixes["t"].to_numpy(float), np.column_stack([fixes["x"].to_numpy(float), fixes["y"].to_numpy(float)])


def velocity_track(fixes: pd.DataFrame, window: int, speed_from: str) -> pd.DataFrame:
    """Velocity-bounded tracker output (t, x, y) at the epochs with a fix (t in s, x, y in m)."""
    t, xy = _table_arrays(fixes)
    return _track_frame(t, velocity_pass(t, xy, window, speed_from)[0])


def _track_frame(t: np.ndarray, tracked: np.ndarray) -> pd.DataFrame:
    fixed = np.isfinite(tracked).all(axis=1)
    return pd.DataFrame({"t": t[fixed], "x": tracked[fixed, 0], "y": tracked[fixed, 1]})


def _run_velocity_pass(data: RunData, p: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, tracked, speed) of velocity_pass over the run's fixes (fixes.epoch_fixes with p["fixes"])
    with p["window"], p["speed_from"]; once per run and settings (RunData.cached): the
    velocity tracker's cells and the KF cells fed its speed share it."""
    def build():
        t, xy = _table_arrays(fixes.epoch_fixes(data, p, p["fixes"]))
        return (t, *velocity_pass(t, xy, p["window"], p["speed_from"]))
    return data.cached(("velocity_pass", fixes.fix_key(data, p, p["fixes"]), p["window"], p["speed_from"]), build)


def run_velocity_track(data: RunData, p: dict) -> pd.DataFrame:
    """The `velocity_tracker` cell with resolved parameters p on one run: velocity_track of its fixes."""
    t, tracked, _ = _run_velocity_pass(data, p)
    return _track_frame(t, tracked)


@dataclass(frozen=True)
class FixSource:
    """One run's per-epoch fixes (fixes.epoch_fixes: t, x, y; NaN x, y without a fix) and the
    velocity algorithm's speed v_hat (m/s) after each fix (NaN: none, or no speed input)."""

    t: np.ndarray
    xy: np.ndarray
    speed: np.ndarray

    @classmethod
    def of(cls, fix_table: pd.DataFrame, velocity: tuple[int, str] | None = None) -> "FixSource":
        """velocity = (window, speed_from) of the velocity tracker whose speed is fed (None: none)."""
        t, xy = _table_arrays(fix_table)
        speed = np.full(len(t), np.nan) if velocity is None else velocity_pass(t, xy, *velocity)[1]
        return cls(t, xy, speed)

    def has_fix(self) -> np.ndarray:
        return np.isfinite(self.xy).all(axis=1)


class FixInitiator:
    """Starts a track at the first epoch with a fix: x0 = [fix, 0, 0], P0 = the motion model's
    initial covariance (core's initiator interface)."""

    def initiate(self, source: FixSource, t: float, motion) -> tuple[np.ndarray, np.ndarray] | None:
        k = int(np.searchsorted(source.t, t))
        if k == len(source.t) or not np.isfinite(source.xy[k]).all():
            return None
        return np.concatenate([source.xy[k], np.zeros(motion.dim - 2)]), motion.initial_covariance()


def _position_and_speed(state: np.ndarray) -> np.ndarray:
    """h(x) = [x, y, ||v||] (m, m, m/s) of PV states [x, y, vx, vy] (..., 4) -> (..., 3)."""
    return np.stack([state[..., 0], state[..., 1], np.hypot(state[..., 2], state[..., 3])], axis=-1)


def _position_and_speed_jacobian(state: np.ndarray) -> np.ndarray:
    """dh/dx of _position_and_speed (..., 3, 4): rows [1 0 0 0], [0 1 0 0], [0 0 vx/||v|| vy/||v||]."""
    norm = np.hypot(state[..., 2], state[..., 3])
    H = np.zeros(state.shape[:-1] + (3, 4))
    H[..., 0, 0], H[..., 1, 1], H[..., 2, 2], H[..., 2, 3] = 1.0, 1.0, state[..., 2] / norm, state[..., 3] / norm
    return H


class FixBank:
    """The KF over fixes of several runs as arrays (a core filter bank): x (runs, 4), P (runs, 4, 4);
    filters.kalman's predict and update (joseph_update) with the epoch's fix, or with the fix
    and the speed v_hat where the run has one (module docstring). An update that is not finite
    is skipped (the prior kept, NIS NaN) and counted in `skipped` (per run)."""

    def __init__(self, sources: list[FixSource], position_sigma_m: float, speed_sigma_mps: float):
        n_epochs = max([len(s.t) for s in sources] + [0])
        self.z, self.speed = np.full((len(sources), n_epochs, 2), np.nan), np.full((len(sources), n_epochs), np.nan)
        for i, s in enumerate(sources):
            self.z[i, :len(s.t)], self.speed[i, :len(s.t)] = s.xy, s.speed
        self.fixed = np.isfinite(self.z).all(axis=2)
        self.H, self.R = fix_measurement(position_sigma_m)
        self.R_speed = np.diag([position_sigma_m**2] * 2 + [speed_sigma_mps**2])
        self.x, self.P = np.zeros((len(sources), 4)), np.zeros((len(sources), 4, 4))
        self.skipped = np.zeros(len(sources), int)

    def start(self, i: int, x0: np.ndarray, P0: np.ndarray, motion) -> None:
        self.x[i], self.P[i] = x0, P0

    def track(self, i: int):
        raise NotImplementedError("the KF over fixes records no forward pass")

    def predict(self, rows: np.ndarray, F, Q, B, u) -> None:
        if len(rows):
            self.x[rows], self.P[rows] = predict(self.x[rows], self.P[rows], F, Q)

    def update(self, rows: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Update the given runs that have a fix at epoch k: (measurements used: 0, 1 for the fix,
        2 with the speed; NIS; lost = False)."""
        fixed = np.flatnonzero(self.fixed[rows, k])
        v = self.speed[rows[fixed], k]
        with_speed = np.isfinite(v) & (np.hypot(self.x[rows[fixed], 2], self.x[rows[fixed], 3]) >= MIN_SPEED_MPS)
        used, nis = np.zeros(len(rows), int), np.full(len(rows), np.nan)
        used[fixed] = 1 + with_speed
        plain, fed = fixed[~with_speed], fixed[with_speed]
        if len(plain):
            r = rows[plain]
            nis[plain] = self._update(r, self.z[r, k] - self.x[r] @ self.H.T, self.H, self.R)
        if len(fed):
            r = rows[fed]
            y = np.column_stack([self.z[r, k], self.speed[r, k]]) - _position_and_speed(self.x[r])
            nis[fed] = self._update(r, y, _position_and_speed_jacobian(self.x[r]), self.R_speed)
        return used, nis, np.zeros(len(rows), bool)

    def _update(self, r: np.ndarray, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
        """joseph_update of runs r with innovations y; their NIS (NaN where skipped)."""
        new = joseph_update(self.x[r], self.P[r], y, H, R)
        self.x[r], self.P[r] = new.x, new.P
        self.skipped[r[~new.ok]] += 1
        return np.where(new.ok, nis(y, new.S_inv), np.nan)

    def estimates(self, rows) -> np.ndarray:
        x, P = self.x[rows], self.P[rows]
        return np.column_stack([x[:, 0], x[:, 1], P[:, 0, 0], P[:, 0, 1], P[:, 1, 1]])


def fix_tracks(sources: list[FixSource], epoch_s: float, accel_sigma_mps2: float, position_sigma_m: float,
               initial_speed_sigma_mps: float, speed_sigma_mps: float) -> list[core.Track]:
    """The KF over the fixes of every source, stepped together by one core.epoch_loop;
    output at the epochs with a fix (module docstring)."""
    motion = fix_motion(epoch_s, accel_sigma_mps2, position_sigma_m, initial_speed_sigma_mps)
    runs = [core.RunInputs(s.t, s, np.zeros(len(s.t), bool), None) for s in sources]
    bank = FixBank(sources, position_sigma_m, speed_sigma_mps)
    out = core.epoch_loop(bank, runs, motion, epoch_s, FixInitiator(), core.CoastingDeleter(np.inf))
    return [core.Track(rows[np.isin(rows[:, 0], source.t[source.has_fix()])], {"resets": resets, "skipped": int(skipped)})
            for source, (rows, resets), skipped in zip(sources, out, bank.skipped)]


def fix_source(data: RunData, p: dict) -> FixSource:
    """What the `kf_tracker` cell with resolved parameters p is fed on one run: the fixes
    (fixes.epoch_fixes with p["fixes"]) and, with p["speed_input"], the velocity tracker's
    speed (p["window"], p["speed_from"]; the run's velocity pass, shared with its velocity cells)."""
    table = fixes.epoch_fixes(data, p, p["fixes"])
    t, xy = _table_arrays(table)
    speed = _run_velocity_pass(data, p)[2] if p["speed_input"] else np.full(len(t), np.nan)
    return FixSource(t, xy, speed)


def kalman_tracks(datas: list[RunData], params: list[dict]) -> list[core.Track]:
    """`kf_tracker` of every (run, resolved parameters) cell: fix_tracks of each cell's
    fix_source, per set of KF settings (the cells sharing them are stepped together)."""
    groups: dict[tuple, list[int]] = {}
    for i, p in enumerate(params):
        key = (p["epoch_s"], p["accel_sigma_mps2"], p["position_sigma_m"], p["initial_speed_sigma_mps"],
               p["speed_sigma_mps"])
        groups.setdefault(key, []).append(i)
    tracks: list[core.Track] = [None] * len(params)
    for key, members in groups.items():
        for i, track in zip(members, fix_tracks([fix_source(datas[i], params[i]) for i in members], *key)):
            tracks[i] = track
    return tracks
