"""filterpy's extended Kalman filter (filterpy.kalman.ExtendedKalmanFilter, the textbook
implementation the project's filters are checked against) behind the interface the filter
loops use (estimators.core: x, P, nis, predict(F, Q, u, B), update_model(model), and
update(z, H, R, hx) for the gate and robust update), so registry estimator `ekf_filterpy`
runs it in the same loops, initiator and deleter as `ekf` and a study shows the reference
beside ours.

filterpy's equations, as in filters.kalman:
  predict:  x <- F x + B u,  P <- F P F^T + Q
  update:   y = z - h(x),  H = dh/dx (x),  S = H P H^T + R,  K = P H^T S^-1,
            x <- x + K y,  P <- (I - K H) P (I - K H)^T + K R K^T
NIS = y^T S^-1 y with filterpy's S^-1 (its attribute SI).
"""

from __future__ import annotations

import numpy as np


class FilterpyEKF:
    """One filterpy ExtendedKalmanFilter with state x (n,) and covariance P (n, n)."""

    def __init__(self, x, P):
        from filterpy.kalman import ExtendedKalmanFilter      # only the runs that use it import filterpy

        self.ekf = ExtendedKalmanFilter(dim_x=len(x), dim_z=1)
        self.ekf.x, self.ekf.P = np.array(x, dtype=float), np.array(P, dtype=float)
        self._nis = float("nan")

    @property
    def x(self) -> np.ndarray:
        return self.ekf.x

    @x.setter
    def x(self, value) -> None:
        self.ekf.x = value

    @property
    def P(self) -> np.ndarray:
        return self.ekf.P

    @P.setter
    def P(self, value) -> None:
        self.ekf.P = value

    @property
    def nis(self) -> float:
        """y^T S^-1 y of the last update (NaN before any)."""
        return self._nis

    def predict(self, F, Q, u=None, B=None) -> None:
        self.ekf.F, self.ekf.Q = F, Q
        self.ekf.B = 0 if u is None else B
        self.ekf.predict(0 if u is None else u)

    def update(self, z, H, R, hx, S=None) -> None:
        """Update with a model linearised elsewhere (the gate and robust update); filterpy
        computes S = H P H^T + R itself (a caller's S is not passed on)."""
        self._update(z, lambda x: H, lambda x: hx, R)

    def update_model(self, model) -> None:
        """Update with a measurement model (z, h(x), jacobian(x), R()): filterpy linearises."""
        self._update(model.z, model.jacobian, model.h, model.R())

    def _update(self, z, jacobian, h, R) -> None:
        self.ekf.update(np.asarray(z, dtype=float), HJacobian=jacobian, Hx=h, R=R)
        self._nis = float(self.ekf.y @ self.ekf.SI @ self.ekf.y)
