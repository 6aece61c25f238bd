"""Motion models of the Bayesian filters as functions of the step length dt (s).

P (random walk, state [x, y]): F = I, Q = sigma_p^2 (dt / T) I, sigma_p the position change
  (m) per estimation period T (paper C), so the variance grows linearly with time.
PV (state [x, y, vx, vy]) and PVA (state [x, y, vx, vy, bx, by], measured acceleration as
  input u with B) as in filters.motion_models (papers A and C).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnloc.filters.motion_models import constant_velocity, position_only, pva

MOTIONS = ("p", "pv", "pva")
STATE_DIM = {"p": 2, "pv": 4, "pva": 6}


@dataclass(frozen=True)
class MotionModel:
    kind: str                      # p | pv | pva
    period_s: float                # T, the period p_sigma_m refers to
    p_sigma_m: float               # P: position change per period (m)
    accel_sigma_mps2: float        # PV: white acceleration; PVA: acceleration input noise (m/s^2)
    bias_walk_sigma: float         # PVA: accelerometer bias random walk (m/s^2/sqrt(s))
    initial_sigma_m: float
    initial_speed_sigma_mps: float
    initial_bias_sigma_mps2: float

    @property
    def dim(self) -> int:
        return STATE_DIM[self.kind]

    def matrices(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(F, Q, B) for a step of dt seconds; B is None without an input."""
        if self.kind == "p":
            F, Q = position_only(self.p_sigma_m * np.sqrt(dt / self.period_s))
            return F, Q, None
        if self.kind == "pv":
            return (*constant_velocity(dt, self.accel_sigma_mps2), None)
        F, B, Q = pva(dt, self.accel_sigma_mps2, self.bias_walk_sigma)
        return F, Q, B

    def initial_covariance(self) -> np.ndarray:
        """P0 = diag(position, speed, bias variances) for the model's state."""
        variances = [self.initial_sigma_m**2] * 2 + [self.initial_speed_sigma_mps**2] * 2 \
            + [self.initial_bias_sigma_mps2**2] * 2
        return np.diag(variances[:self.dim])
