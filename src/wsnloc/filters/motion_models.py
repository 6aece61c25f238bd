"""Motion models: state transition F, input matrix B and process noise Q for a 2-D mobile
(P and PV also in 3-D: `axes` = 3, the same blocks per axis, state [x, y, z] / [x, y, z, vx, vy, vz]).

P (random walk), state [x, y]:            F = I2, Q = diag(s_x^2, s_y^2)           (paper C)
PV (constant velocity, white accel.), state [x, y, vx, vy]:
  F = [[I2, dt I2], [0, I2]],  Q = G diag(sa_x^2, sa_y^2) G^T,  G = [[dt^2/2 I2], [dt I2]]   (papers A, C)
Unicycle with odometry (state [x, y, hx, hy], h = (cos theta, sin theta) the heading as a unit
vector, inputs speed v and yaw rate w; the tag moves along its heading):
  h(t + dt) = Rot(w dt) h(t),  p(t + dt) = p(t) + v Int_0^dt Rot(w s) ds h(t),
  F = [[I2, v M], [0, Rot(w dt)]],  M = [[sin(w dt), cos(w dt) - 1], [1 - cos(w dt), sin(w dt)]] / w
  (M -> dt I2 as w -> 0); linear in the state for known (v, w), so the linear predict is exact.
  Q = diag(s_v^2 dt^2 I2, s_w^2 dt^2 I2): a speed error s_v (m/s) and a yaw-rate error s_w (rad/s)
  held over the step (the position error along, the heading error across the heading, bounded
  by isotropic blocks).
PVA (measured acceleration as input, accelerometer bias states), state [x, y, vx, vy, bx, by]:
  F = [[I2, dt I2, -dt^2/2 I2], [0, I2, -dt I2], [0, 0, I2]],  B = [[dt^2/2 I2], [dt I2], [0]],
  Q = B sa^2 B^T + blockdiag(0, 0, s_b^2 dt I2)  (accelerometer noise through B, bias random walk)  (paper C)
"""

from __future__ import annotations

import numpy as np


def constant_velocity(dt: float, accel_sigma_x: float, accel_sigma_y: float | None = None, axes: int = 2):
    """(F, Q) of the PV model for a step dt (s) and white-acceleration sigmas (m/s^2); with
    axes = 3 the z axis has accel_sigma_x too."""
    sy = accel_sigma_x if accel_sigma_y is None else accel_sigma_y
    sigmas = [accel_sigma_x, sy] + [accel_sigma_x] * (axes - 2)
    F = np.eye(2 * axes)
    G = np.zeros((2 * axes, axes))
    for axis in range(axes):
        F[axis, axes + axis] = dt
        G[axis, axis], G[axes + axis, axis] = dt**2 / 2.0, dt
    Q = G @ np.diag(np.square(sigmas)) @ G.T
    return F, Q


def position_only(sigma_x: float, sigma_y: float | None = None, axes: int = 2):
    """(F, Q) of the P model; sigmas in m per step (z: sigma_x with axes = 3)."""
    sy = sigma_x if sigma_y is None else sigma_y
    return np.eye(axes), np.diag(np.square([sigma_x, sy] + [sigma_x] * (axes - 2)))


def unicycle(dt: float, speed_mps: float, yaw_rate_rps: float, speed_sigma_mps: float, yaw_rate_sigma_rps: float):
    """(F, Q) of the unicycle model with odometry (module docstring) for a step dt (s), the
    measured speed v (m/s) and yaw rate w (rad/s) and their error sigmas."""
    angle = yaw_rate_rps * dt
    c, s = np.cos(angle), np.sin(angle)
    if abs(angle) < 1e-9:
        M = dt * np.eye(2)
    else:
        M = np.array([[s, c - 1.0], [1.0 - c, s]]) / yaw_rate_rps
    F = np.eye(4)
    F[:2, 2:] = speed_mps * M
    F[2:, 2:] = [[c, -s], [s, c]]
    Q = np.diag([(speed_sigma_mps * dt) ** 2] * 2 + [(yaw_rate_sigma_rps * dt) ** 2] * 2)
    return F, Q


def pva(dt: float, accel_sigma: float, bias_walk_sigma: float):
    """(F, B, Q) of the PVA model; accel_sigma in m/s^2, bias_walk_sigma in m/s^2/sqrt(s)."""
    F, B = np.eye(6), np.zeros((6, 2))
    for axis in range(2):
        F[axis, 2 + axis], F[axis, 4 + axis], F[2 + axis, 4 + axis] = dt, -dt**2 / 2, -dt
        B[axis, axis], B[2 + axis, axis] = dt**2 / 2, dt
    Q = B @ B.T * accel_sigma**2
    Q[4:, 4:] += np.eye(2) * bias_walk_sigma**2 * dt
    return F, B, Q
