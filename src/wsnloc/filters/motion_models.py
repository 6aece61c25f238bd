"""Motion models: state transition F and process noise Q for a 2-D mobile.

PV (constant velocity, white acceleration), state [x, y, vx, vy]:
  F = [[I2, dt I2], [0, I2]],  Q = G diag(sa_x^2, sa_y^2) G^T,  G = [[dt^2/2 I2], [dt I2]].
"""

from __future__ import annotations

import numpy as np


def constant_velocity(dt: float, accel_sigma_x: float, accel_sigma_y: float | None = None):
    """(F, Q) of the PV model for a step dt (s) and white-acceleration sigmas (m/s^2)."""
    sy = accel_sigma_x if accel_sigma_y is None else accel_sigma_y
    eye = np.eye(2)
    F = np.block([[eye, dt * eye], [np.zeros((2, 2)), eye]])
    G = np.vstack([dt**2 / 2.0 * eye, dt * eye])
    Q = G @ np.diag([accel_sigma_x**2, sy**2]) @ G.T
    return F, Q
