"""Motion models of the Bayesian filters as functions of the step length dt (s).

P (random walk, state [x, y]): F = I, Q = sigma_p^2 (dt / T) I, sigma_p the position change
  (m) per estimation period T (paper C), so the variance grows linearly with time.
PV (state [x, y, vx, vy]) and PVA (state [x, y, vx, vy, bx, by], measured acceleration as
  input u with B) as in filters.motion_models (papers A and C).
P and PV in 3-D (`dimensions` 3): state [x, y, z] / [x, y, z, vx, vy, vz], the same model on
  each axis (filters.motion_models, axes = 3); the default 2 keeps the tag at the fixed tag
  height of the campaign (estimators.run_data) where the data are planar.
Odometry (state [x, y, hx, hy], the heading as a unit vector): the unicycle model driven by
  the odometry's speed and yaw rate u = (v, w) (filters.motion_models.unicycle); F depends on
  the input (`input_dependent`). Without odometry in a step (u not finite) the position is held
  with Q = (initial_speed_sigma_mps dt)^2 on it (speed unknown) and the heading kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from wsnloc.filters.motion_models import constant_velocity, position_only, pva, unicycle

MOTIONS = ("p", "pv", "pva", "odometry")
STATE_DIM = {"p": 2, "pv": 4, "pva": 6, "odometry": 4}       # in 2-D
STEP_CACHE = 4096                  # step lengths whose (F, Q, B) are kept (sequential updates repeat a few dt)
THREE_D = ("p", "pv")              # the models with a 3-D state
HEADING_VARIANCE = 0.5             # variance of cos(theta) and sin(theta) for a uniform unknown heading


@dataclass(frozen=True)
class MotionModel:
    kind: str                      # p | pv | pva | odometry
    period_s: float                # T, the period p_sigma_m refers to
    p_sigma_m: float               # P: position change per period (m)
    accel_sigma_mps2: float        # PV: white acceleration; PVA: acceleration input noise (m/s^2)
    bias_walk_sigma: float         # PVA: accelerometer bias random walk (m/s^2/sqrt(s))
    initial_sigma_m: float
    initial_speed_sigma_mps: float
    initial_bias_sigma_mps2: float
    dimensions: int = 2            # position axes of the state: 2 or 3 (THREE_D kinds)
    odometry_speed_sigma_mps: float = 0.0      # odometry: speed error held over a step
    odometry_yaw_rate_sigma_rps: float = 0.0   # odometry: yaw-rate error held over a step

    def __post_init__(self):
        if self.dimensions not in (2, 3) or (self.dimensions == 3 and self.kind not in THREE_D):
            raise ValueError(f"motion {self.kind!r} has no {self.dimensions}-D state "
                             f"(3-D: {', '.join(THREE_D)}; dimensions 2 or 3)")

    @property
    def dim(self) -> int:
        return STATE_DIM[self.kind] // 2 * self.dimensions

    @property
    def input_dependent(self) -> bool:
        """Whether F depends on the step's input (odometry): matrices(dt, u) per step."""
        return self.kind == "odometry"

    def matrices(self, dt: float, u: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(F, Q, B) for a step of dt seconds; B is None without an input (B u). u: the step's
        odometry (v, w) for the odometry model (F depends on it), unused by the others, whose
        matrices are computed once per (model, dt) and shared (read-only): a sequential filter
        steps over the same few intervals of its anchors' schedule again and again."""
        if self.kind == "odometry":
            return self._matrices(dt, u)
        return _step_matrices(self, float(dt))

    def _matrices(self, dt: float, u: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        if self.kind == "p":
            F, Q = position_only(self.p_sigma_m * np.sqrt(dt / self.period_s), axes=self.dimensions)
            return F, Q, None
        if self.kind == "pv":
            return (*constant_velocity(dt, self.accel_sigma_mps2, axes=self.dimensions), None)
        if self.kind == "odometry":
            if u is None or not np.all(np.isfinite(u)):
                Q = np.zeros((4, 4))
                Q[0, 0] = Q[1, 1] = (self.initial_speed_sigma_mps * dt) ** 2
                return np.eye(4), Q, None
            return (*unicycle(dt, u[0], u[1], self.odometry_speed_sigma_mps, self.odometry_yaw_rate_sigma_rps), None)
        F, B, Q = pva(dt, self.accel_sigma_mps2, self.bias_walk_sigma)
        return F, Q, B

    def initial_covariance(self) -> np.ndarray:
        """P0 = diag(position, speed, bias variances) for the model's state (odometry: position,
        then HEADING_VARIANCE for each heading component: the heading is unknown, mean 0)."""
        if self.kind == "odometry":
            return np.diag([self.initial_sigma_m**2] * 2 + [HEADING_VARIANCE] * 2)
        n = self.dimensions
        variances = [self.initial_sigma_m**2] * n + [self.initial_speed_sigma_mps**2] * n \
            + [self.initial_bias_sigma_mps2**2] * n
        return np.diag(variances[:self.dim])


@lru_cache(maxsize=STEP_CACHE)
def _step_matrices(motion: MotionModel, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """MotionModel.matrices of an input-independent model, computed once per (model, dt), read-only."""
    matrices = motion._matrices(dt, None)
    for m in matrices:
        if m is not None:
            m.flags.writeable = False
    return matrices
