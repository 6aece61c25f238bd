"""Motion models: state transition F, input matrix B and process noise Q for a 2-D mobile.

P (random walk), state [x, y]:            F = I2, Q = diag(s_x^2, s_y^2)           (paper C)
PV (constant velocity, white accel.), state [x, y, vx, vy]:
  F = [[I2, dt I2], [0, I2]],  Q = G diag(sa_x^2, sa_y^2) G^T,  G = [[dt^2/2 I2], [dt I2]]   (papers A, C)
PVA (measured acceleration as input, accelerometer bias states), state [x, y, vx, vy, bx, by]:
  F = [[I2, dt I2, -dt^2/2 I2], [0, I2, -dt I2], [0, 0, I2]],  B = [[dt^2/2 I2], [dt I2], [0]],
  Q = B sa^2 B^T + blockdiag(0, 0, s_b^2 dt I2)  (accelerometer noise through B, bias random walk)  (paper C)
"""

from __future__ import annotations

import numpy as np


def constant_velocity(dt: float, accel_sigma_x: float, accel_sigma_y: float | None = None):
    """(F, Q) of the PV model for a step dt (s) and white-acceleration sigmas (m/s^2)."""
    sy = accel_sigma_x if accel_sigma_y is None else accel_sigma_y
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    G = np.zeros((4, 2))
    G[0, 0] = G[1, 1] = dt**2 / 2.0
    G[2, 0] = G[3, 1] = dt
    Q = G @ np.diag([accel_sigma_x**2, sy**2]) @ G.T
    return F, Q


def position_only(sigma_x: float, sigma_y: float | None = None):
    """(F, Q) of the P model; sigmas in m per step."""
    sy = sigma_x if sigma_y is None else sigma_y
    return np.eye(2), np.diag([sigma_x**2, sy**2])


def pva(dt: float, accel_sigma: float, bias_walk_sigma: float):
    """(F, B, Q) of the PVA model; accel_sigma in m/s^2, bias_walk_sigma in m/s^2/sqrt(s)."""
    F, B = np.eye(6), np.zeros((6, 2))
    for axis in range(2):
        F[axis, 2 + axis], F[axis, 4 + axis], F[2 + axis, 4 + axis] = dt, -dt**2 / 2, -dt
        B[axis, axis], B[2 + axis, axis] = dt**2 / 2, dt
    Q = B @ B.T * accel_sigma**2
    Q[4:, 4:] += np.eye(2) * bias_walk_sigma**2 * dt
    return F, B, Q
