"""Trackers over a sequence of fixes (paper D): the velocity-bounded tracker and a
constant-velocity Kalman filter with the fixes as position measurements.

KF: state [x, y, vx, vy], PV model with white acceleration sigma_a over the epoch T;
z = [x, y] with R = sigma_fix^2 I; P0 = diag(sigma_fix^2, sigma_fix^2, sigma_v^2, sigma_v^2).
It starts at the first fix, predicts at every later epoch (with or without a fix) and
is updated with each fix. Both trackers output only at epochs that have a fix.

Fed the velocity algorithm's speed (paper D §4.2: "z_k is populated with the position estimates
coming from Min-Max ... while the velocity algorithm provides speed estimates"): the velocity
tracker's window speed v_hat (eq. 1) at the fix joins the update as a third component,
z = [x, y, v_hat], h(x) = [x, y, ||v||], H_3 = [0, 0, vx / ||v||, vy / ||v||], R_33 = sigma_v^2;
position-only where v_hat is undefined (window not filled) or ||v|| < MIN_SPEED_MPS (no direction).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from wsnloc.filters.kalman import KalmanFilter
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker


def kalman_matrices(epoch_s: float, accel_sigma_mps2: float, position_sigma_m: float,
                    initial_speed_sigma_mps: float) -> tuple:
    """(F, Q, H, R, P0) of the KF over fixes."""
    F, Q = constant_velocity(epoch_s, accel_sigma_mps2)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = np.eye(2) * position_sigma_m**2
    P0 = np.diag([position_sigma_m**2] * 2 + [initial_speed_sigma_mps**2] * 2)
    return F, Q, H, R, P0


def velocity_track(fixes: pd.DataFrame, window: int, speed_from: str) -> pd.DataFrame:
    """Velocity-bounded tracker output (t, x, y) at the epochs with a fix (t in s, x, y in m)."""
    tracker = VelocityBoundedTracker(window, speed_from)
    columns = (fixes[c].to_numpy(float).tolist() for c in ("t", "x", "y"))
    rows = [(t, *tracker.update(t, x, y)) for t, x, y in zip(*columns) if math.isfinite(x) and math.isfinite(y)]
    return pd.DataFrame(rows, columns=["t", "x", "y"])


MIN_SPEED_MPS = 1e-3     # below this predicted speed ||v|| has no direction: the speed component is left out


def kalman_track(fixes: pd.DataFrame, matrices: tuple, speed: tuple | None = None) -> pd.DataFrame:
    """KF output (t, x, y and the position covariance) at the epochs with a fix; `speed` =
    (window, speed_from, sigma_v in m/s) feeds the velocity algorithm's speed (module docstring)."""
    F, Q, H, R, P0 = matrices
    velocity = VelocityBoundedTracker(speed[0], speed[1]) if speed is not None else None
    kf, rows = None, []
    for t, x, y in fixes[["t", "x", "y"]].itertuples(index=False):
        has_fix = np.isfinite(x) and np.isfinite(y)
        if kf is not None:
            kf.predict()
        if not has_fix:
            continue
        if velocity is not None:
            velocity.update(t, x, y)
        if kf is None:
            kf = KalmanFilter(np.array([x, y, 0.0, 0.0]), P0, F, Q, H, R)
        elif velocity is not None and math.isfinite(velocity.speed) and math.hypot(*kf.x[2:]) >= MIN_SPEED_MPS:
            kf.update(np.array([x, y, velocity.speed]), H=_position_and_speed_jacobian(kf.x),
                      R=np.diag([R[0, 0], R[1, 1], speed[2] ** 2]), hx=_position_and_speed(kf.x))   # EKF update
        else:
            kf.update(np.array([x, y]))
        rows.append((t, kf.x[0], kf.x[1], kf.P[0, 0], kf.P[0, 1], kf.P[1, 1]))
    return pd.DataFrame(rows, columns=["t", "x", "y", "p_xx", "p_xy", "p_yy"])


def _position_and_speed(state: np.ndarray) -> np.ndarray:
    """h(x) = [x, y, ||v||] (m, m, m/s) of the PV state [x, y, vx, vy]."""
    return np.array([state[0], state[1], math.hypot(state[2], state[3])])


def _position_and_speed_jacobian(state: np.ndarray) -> np.ndarray:
    """dh/dx of _position_and_speed: rows [1 0 0 0], [0 1 0 0], [0 0 vx/||v|| vy/||v||]."""
    norm = math.hypot(state[2], state[3])
    return np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, state[2] / norm, state[3] / norm]])
