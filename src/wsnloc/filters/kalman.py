"""Linear Kalman filter with the Joseph-form covariance update.

State x (n,), covariance P (n, n), transition F, process noise Q, observation H, noise R.
  predict:  x <- F x (+ B u),        P <- F P F^T + Q
  update:   y = z - H x,  S = H P H^T + R,  K = P H^T S^-1
            x <- x + K y,  P <- (I - K H) P (I - K H)^T + K R K^T      (Joseph form)
The attribute names follow filterpy.kalman.KalmanFilter so results can be compared
one to one; the innovation y, its covariance S and NIS = y^T S^-1 y of the last update
are kept for diagnostics. An update with a singular S or a non-finite result (real data:
a degenerate geometry, a non-finite model) is skipped, the prior kept, and counted in
`guards.skipped` (filters.numerics).
"""

from __future__ import annotations

import numpy as np

from wsnloc.filters.numerics import Guards, usable


def inverse(S: np.ndarray) -> np.ndarray:
    """S^-1 of a square S; a 1 x 1 S gives [[1 / s]] directly (the value LAPACK's LU solve in
    numpy.linalg.inv computes, without its call overhead)."""
    if S.shape == (1, 1):
        return 1.0 / S
    return np.linalg.inv(S)


class KalmanFilter:
    def __init__(self, x, P, F, Q, H, R, guards: Guards | None = None):
        self.x = np.asarray(x, dtype=float).copy()
        self.P = np.asarray(P, dtype=float).copy()
        self.F = np.asarray(F, dtype=float)
        self.Q = np.asarray(Q, dtype=float)
        self.H = np.asarray(H, dtype=float)
        self.R = np.asarray(R, dtype=float)
        self.y = np.zeros(self.H.shape[0])
        self.S = np.eye(self.H.shape[0])
        self.K = np.zeros((len(self.x), self.H.shape[0]))
        self._S_inv = None
        self._eye = np.eye(len(self.x))
        self.guards = guards if guards is not None else Guards()

    def predict(self, F=None, Q=None, u=None, B=None) -> None:
        """x <- F x (+ B u), P <- F P F^T + Q; F and Q default to the filter's own (a step of
        another length passes its own matrices)."""
        F = self.F if F is None else F
        Q = self.Q if Q is None else Q
        self.x = F @ self.x
        if u is not None:
            self.x = self.x + B @ u
        self.P = F @ self.P @ F.T + Q

    def update(self, z, H=None, R=None, hx=None) -> None:
        """Measurement update; `hx` is the predicted measurement h(x) of a linearised model
        (default H x). The measurement size may change from call to call."""
        H = self.H if H is None else H
        R = self.R if R is None else R
        y = z - (H @ self.x if hx is None else hx)
        PHt = self.P @ H.T
        S = H @ PHt + R
        try:
            S_inv = inverse(S)
        except np.linalg.LinAlgError:
            S_inv = np.full_like(S, np.nan)
        K = PHt @ S_inv
        x = self.x + K @ y
        joseph = self._eye - K @ H
        P = joseph @ self.P @ joseph.T + K @ R @ K.T
        if not usable(x, P):
            self.guards.skipped += 1
            return
        self.y, self.S, self.K, self.x, self.P, self._S_inv = y, S, K, x, P, S_inv

    @property
    def nis(self) -> float:
        """Normalised innovation squared y^T S^-1 y of the last update (NaN before any)."""
        return float("nan") if self._S_inv is None else float(self.y @ self._S_inv @ self.y)


class ExtendedKalmanFilter(KalmanFilter):
    """EKF: linear motion model (F, Q, optional input B u), non-linear measurement z = h(x) + v.

    update_nonlinear linearises at the predicted state: H = dh/dx (x), y = z - h(x), then
    the Joseph-form update above (filterpy.kalman.ExtendedKalmanFilter.update does the same).
    """

    def __init__(self, x, P, F, Q, guards: Guards | None = None):
        n = len(np.asarray(x))
        super().__init__(x, P, F, Q, np.zeros((1, n)), np.eye(1), guards)

    def update_nonlinear(self, z, h, jacobian, R) -> None:
        self.update(z, H=jacobian(self.x), R=R, hx=h(self.x))

    def update_model(self, model) -> None:
        """Update with a measurement model object (z, h(x), jacobian(x), R())."""
        self.update(model.z, H=model.jacobian(self.x), R=model.R(), hx=model.h(self.x))
