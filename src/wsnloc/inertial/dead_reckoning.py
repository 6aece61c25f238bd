"""Planar dead reckoning from a 5 Hz IMU stream (paper B, eq. 4-6).

Per step k -> k+1 of length dt_k:
  theta_{k+1} = theta_k + w_k dt_k                       (z gyro)
  a_k (floor) = R(theta_k + w_k dt_k / 2) [ax_k, ay_k]   (body -> floor, mid-step heading)
  p_{k+1} = p_k + v_k dt_k + a_k dt_k^2 / 2
  v_{k+1} = v_k + a_k dt_k
Gravity is on body z only (the cart stays level), so the horizontal axes need no gravity
removal beyond the sensor bias. The inputs are held over each step (exact for inputs that
are constant per step; first order in dt for smooth ones). Rotating with the mid-step
heading instead of theta_k halves the turn error at 5 Hz; otherwise this is paper B's eq. 4.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd


@dataclass
class ImuBias:
    """Horizontal accelerometer bias (m/s^2) and z-gyro bias (rad/s)."""

    ax: float = 0.0
    ay: float = 0.0
    gz: float = 0.0


def static_bias(imu: pd.DataFrame, duration_s: float) -> ImuBias:
    """Mean sensor output over the first `duration_s` seconds, when the mobile is known to rest.

    Paper B: the gyro bias "can be modeled by recording the output of the sensor in static
    conditions"; the same holds for the horizontal accelerometer axes of a level cart.
    """
    if duration_s <= 0 or len(imu) == 0:
        return ImuBias()
    still = imu[imu["t"] <= imu["t"].iloc[0] + duration_s]
    return ImuBias(float(still["ax"].mean()), float(still["ay"].mean()), float(still["gz"].mean()))


def dead_reckon(imu: pd.DataFrame, x0: float, y0: float, heading0: float,
                bias: ImuBias | None = None) -> pd.DataFrame:
    """Positions (m), speeds (m/s) and heading (rad) at the IMU sample times, starting at rest."""
    bias = bias or ImuBias()
    t = imu["t"].to_numpy(float)
    ax = imu["ax"].to_numpy(float) - bias.ax
    ay = imu["ay"].to_numpy(float) - bias.ay
    gz = imu["gz"].to_numpy(float) - bias.gz
    if len(t) == 0:
        return pd.DataFrame({name: np.zeros(0) for name in ("t", "x", "y", "vx", "vy", "heading")})
    dt = np.diff(t)
    heading = _accumulate(heading0, gz[:-1] * dt)
    mid = heading[:-1] + 0.5 * gz[:-1] * dt
    c, s = np.cos(mid), np.sin(mid)
    a_x, a_y = c * ax[:-1] - s * ay[:-1], s * ax[:-1] + c * ay[:-1]
    vx, vy = _accumulate(0.0, a_x * dt), _accumulate(0.0, a_y * dt)
    x = _accumulate(x0, vx[:-1] * dt, 0.5 * a_x * dt * dt)
    y = _accumulate(y0, vy[:-1] * dt, 0.5 * a_y * dt * dt)
    return pd.DataFrame({"t": t, "x": x, "y": y, "vx": vx, "vy": vy, "heading": heading})


def _accumulate(start: float, *terms: np.ndarray) -> np.ndarray:
    """s_0 = start, s_{k+1} = (s_k + terms[0][k]) + terms[1][k] + ... rounded after each
    addition, as the step-by-step loop adds them: one sequential np.cumsum over the terms
    interleaved (start, a_0, b_0, a_1, b_1, ...), read after each step's last term."""
    steps = np.column_stack(terms).ravel()
    sums = np.cumsum(np.concatenate([[float(start)], steps]))
    return sums[::len(terms)]


def floor_acceleration(imu: pd.DataFrame, heading0: float, bias: ImuBias | None = None) -> pd.DataFrame:
    """Horizontal specific force rotated into the floor frame (m/s^2), heading from the z gyro.

    theta_{k+1} = theta_k + w_k dt; a_floor = R(theta_k) [ax - bx, ay - by].
    """
    bias = bias or ImuBias()
    t = imu["t"].to_numpy(float)
    gz = imu["gz"].to_numpy(float) - bias.gz
    heading = heading0 + np.concatenate([[0.0], np.cumsum(gz[:-1] * np.diff(t))]) if len(t) else np.array([])
    ax = imu["ax"].to_numpy(float) - bias.ax
    ay = imu["ay"].to_numpy(float) - bias.ay
    c, s = np.cos(heading), np.sin(heading)
    return pd.DataFrame({"t": t, "ax": c * ax - s * ay, "ay": s * ax + c * ay})
