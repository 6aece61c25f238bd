"""Unscented Kalman filter with scaled sigma points (van der Merwe), additive noise.

State x (n,), covariance P (n, n). Scaled sigma points and weights, lambda = alpha^2 (n + kappa) - n:
  chi_0 = x,  chi_i = x + L_i,  chi_{n+i} = x - L_i   (i = 1..n),  L L^T = (n + lambda) P (Cholesky, L_i its columns)
  Wm_0 = lambda / (n + lambda),  Wc_0 = Wm_0 + 1 - alpha^2 + beta,  Wm_i = Wc_i = 1 / (2 (n + lambda))
predict (linear motion model, done exactly):  x <- F x (+ B u),  P <- F P F^T + Q
  Pushing the sigma points through a linear F gives the same mean and covariance (the points'
  weighted mean is x and their weighted covariance is P), so the exact form is used: cheaper,
  and it needs no Cholesky factor of P.
update with a measurement model z = h(x) + v, v ~ N(0, R); the sigma points are drawn from
the current (x, P), i.e. after any predict (Q included), as in Wan & van der Merwe's additive-noise UKF:
  Z_i = h(chi_i),  z_hat = sum Wm_i Z_i,  S = sum Wc_i (Z_i - z_hat)(Z_i - z_hat)^T + R
  Pxz = sum Wc_i (chi_i - x)(Z_i - z_hat)^T,  K = Pxz S^-1,  y = z - z_hat
  x <- x + K y,  P <- P - K S K^T,  NIS = y^T S^-1 y
computed as the Kalman update (filters.kalman.joseph_update, whose Joseph form equals P - K S K^T
here) of the sigma points' statistical linear regression (`linearise`: H = Pxz^T P^-1, R + Omega),
so the EKF's gate and robust updates apply to it unchanged.
Omega and the posterior P are symmetrised, (A + A^T) / 2: the Cholesky factor reads one triangle
of P while H = Pxz^T P^-1 reads both, so a rounding asymmetry fed back through Omega and the
update grew about 1.9x per update (on a real outdoor UWB run with epoch updates, range sigma
0.15 m and accel 1.5 m/s^2, from 1e-9 to the size of P in ~40 updates, then P indefinite and the
track at 1e7 m; tests/test_ukf.py).
On real data (filters.numerics): an indefinite P is regularised before its Cholesky factor
is taken, and an update with a singular S or a non-finite result is skipped; both counted.
With predict/update pairs this is exactly filterpy.kalman.UnscentedKalmanFilter with
MerweScaledSigmaPoints (which redraws its points at the end of predict).
"""

from __future__ import annotations

import numpy as np

from wsnloc.filters.kalman import joseph_update, nis
from wsnloc.filters.numerics import Guards, safe_cholesky


class UnscentedKalmanFilter:
    """UKF over a linear motion model and any measurement model with z, h_many(X), R().

    alpha (> 0) sets the sigma points' spread, beta = 2 is optimal for Gaussian priors,
    kappa a secondary scaling. The defaults alpha = 1, kappa = 0 (lambda = 0) put the points
    at x +- sqrt(n) * (columns of chol P) with non-negative weights, so S and P stay
    positive semi-definite.
    """

    def __init__(self, x, P, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0, guards: Guards | None = None):
        if alpha <= 0:
            raise ValueError(f"UKF alpha must be > 0, got {alpha}")
        self.x = np.asarray(x, dtype=float).copy()
        self.P = np.asarray(P, dtype=float).copy()
        n = len(self.x)
        lam = alpha**2 * (n + kappa) - n
        if n + lam <= 0:
            raise ValueError(f"UKF needs alpha^2 (n + kappa) > 0; got alpha={alpha}, kappa={kappa}, n={n}")
        self._spread = n + lam
        self.Wm = np.full(2 * n + 1, 0.5 / self._spread)
        self.Wc = self.Wm.copy()
        self.Wm[0] = lam / self._spread
        self.Wc[0] = self.Wm[0] + 1.0 - alpha**2 + beta
        self.y = np.zeros(0)
        self.S = np.zeros((0, 0))
        self._S_inv = None
        self.guards = guards if guards is not None else Guards()

    def sigma_points(self) -> np.ndarray:
        """(2n + 1, n) scaled sigma points of the current (x, P), ordered chi_0, chi_1..n, chi_n+1..2n
        (an indefinite P is regularised first: filters.numerics.safe_cholesky, counted)."""
        L = safe_cholesky(self._spread * self.P, self.guards)
        return np.vstack([self.x, self.x + L.T, self.x - L.T])

    def predict(self, F, Q, u=None, B=None) -> None:
        """x <- F x (+ B u), P <- F P F^T + Q (exact; see the module docstring)."""
        self.x = F @ self.x
        if u is not None:
            self.x = self.x + B @ u
        self.P = F @ self.P @ F.T + Q

    def linearise(self, h_many) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Statistical linear regression of z = h(x) over the sigma points of (x, P), h_many(X)
        (N, m) evaluating h at every row of X (N, n) (the measurement models' h_many):
        z_hat = sum Wm_i h(chi_i), H = Pxz^T P^-1 and the linearisation error
        Omega = Pzz - H P H^T (Pzz = sum Wc_i (Z_i - z_hat)(Z_i - z_hat)^T). The linear update
        `update(z, H, R + Omega, z_hat)` is then the unscented update: S = Pzz + R, K = Pxz S^-1
        (Garcia-Fernandez et al., posterior linearisation, 2015). So a gate or a robust
        reweighting (estimators.robust) applies to the UKF as to the EKF. A singular P gives a
        NaN H, and the update is then skipped (counted)."""
        chi = self.sigma_points()
        Z = h_many(chi)                                       # (2n + 1, m)
        z_hat = self.Wm @ Z
        dZ = Z - z_hat
        Pzz = (self.Wc[:, None] * dZ).T @ dZ
        Pxz = (self.Wc[:, None] * (chi - self.x)).T @ dZ
        try:
            H = np.linalg.solve(self.P, Pxz).T
        except np.linalg.LinAlgError:
            H = np.full(Pxz.T.shape, np.nan)
        omega = Pzz - H @ Pxz
        return z_hat, H, 0.5 * (omega + omega.T)

    def update(self, z, H, R, hx, S=None) -> None:
        """Linear update with the predicted measurement hx and the regression H (R includes
        linearise's Omega): y = z - hx and the Kalman update of filters.kalman.joseph_update,
        whose S = H P H^T + R is Pzz + R and whose Joseph-form P equals P - K S K^T (K = Pxz S^-1);
        S: that S when the caller computed it (a gate)."""
        y = z - hx
        new = joseph_update(self.x, self.P, y, H, R, S)
        if not new.ok:                         # a singular S or a non-finite model: the prior is kept
            self.guards.skipped += 1
            return
        self.S, self._S_inv, self.y, self.x = new.S, new.S_inv, y, new.x
        self.P = 0.5 * (new.P + new.P.T)

    def update_model(self, model) -> None:
        """Unscented update with model.z, model.h_many and model.R() (the size of z may vary):
        linearise, then update."""
        hx, H, omega = self.linearise(model.h_many)
        self.update(model.z, H, model.R() + omega, hx)

    @property
    def nis(self) -> float:
        """Normalised innovation squared y^T S^-1 y of the last update (NaN before any)."""
        return float("nan") if self._S_inv is None else float(nis(self.y, self._S_inv))
