"""Linear Kalman filter with the Joseph-form covariance update.

State x (n,), covariance P (n, n), transition F, process noise Q, observation H, noise R.
  predict:  x <- F x (+ B u),        P <- F P F^T + Q
  update:   y = z - H x,  S = H P H^T + R,  K = P H^T S^-1
            x <- x + K y,  P <- (I - K H) P (I - K H)^T + K R K^T      (Joseph form)
For a diagonal R (independent measurements, e.g. a bank's padded ranges / RSS values),
diagonal_update computes the same update in information form with only n x n matrices:
  P <- (P^-1 + H^T R^-1 H)^-1 = (I + P H^T R^-1 H)^-1 P,  x <- x + P H^T R^-1 y,  NIS = y^T R^-1 (y - H (x+ - x))
(the Woodbury identity S^-1 = R^-1 - R^-1 H P+ H^T R^-1); equal to joseph_update up to rounding.
The attribute names follow filterpy.kalman.KalmanFilter so results can be compared
one to one; the innovation y, its covariance S and NIS = y^T S^-1 y of the last update
are kept for diagnostics. An update with a singular S or a non-finite result (real data:
a degenerate geometry, a non-finite model) is skipped, the prior kept, and counted in
`guards.skipped` (filters.numerics).
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

from wsnloc.filters.numerics import Guards


def inverse(S: np.ndarray) -> np.ndarray:
    """S^-1 of square matrices S (..., m, m); a 1 x 1 S gives 1 / s directly (the value LAPACK's LU
    solve in numpy.linalg.inv computes, without its call overhead); a singular S gives NaN (its
    update is then skipped), the others of a stack their inverse."""
    if S.shape[-2:] == (1, 1):
        return 1.0 / S
    try:
        return np.linalg.inv(S)
    except np.linalg.LinAlgError:
        out = np.full_like(S, np.nan)
        for i in np.ndindex(S.shape[:-2]):
            try:
                out[i] = np.linalg.inv(S[i])
            except np.linalg.LinAlgError:
                pass                              # singular: NaN
        return out


@lru_cache(maxsize=None)
def identity(n: int) -> np.ndarray:
    """The n x n identity, built once per size (read-only): the Joseph form's I - K H of every update."""
    eye = np.eye(n)
    eye.flags.writeable = False
    return eye


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray, Bu: np.ndarray | None = None):
    """The Kalman prediction x <- F x (+ B u), P <- F P F^T + Q, for one filter and for a bank
    (leading axes a batch, as joseph_update): x (..., n), P (..., n, n), F and Q (..., n, n),
    Bu (..., n) the input term B u (None: none). Returns (x, P)."""
    x = (F @ x[..., None])[..., 0]
    if Bu is not None:
        x = x + Bu
    return x, F @ P @ F.swapaxes(-1, -2) + Q


class Update(NamedTuple):
    """What joseph_update computes; `ok` (...,) is False where the result is not finite (the
    update is then skipped: x, P keep the prior)."""

    x: np.ndarray
    P: np.ndarray
    S: np.ndarray
    S_inv: np.ndarray
    K: np.ndarray
    ok: np.ndarray


def innovation_covariance(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """S = H P H^T + R (..., m, m), evaluated as H (P H^T) + R, as joseph_update does."""
    return H @ (P @ H.swapaxes(-1, -2)) + R


def joseph_update(x: np.ndarray, P: np.ndarray, y: np.ndarray, H: np.ndarray, R: np.ndarray,
                  S: np.ndarray | None = None) -> Update:
    """The Kalman measurement update (module docstring), written once for one filter and for a
    bank of them: any leading axes are a batch (one run: none; many runs: (runs,)), broadcast
    between the arguments: x (..., n), P (..., n, n), innovation y = z - h(x) (..., m),
    H (..., m, n), R (..., m, m). S = H P H^T + R, K = P H^T S^-1, x <- x + K y,
    P <- (I - K H) P (I - K H)^T + K R K^T. S: the innovation covariance when the caller has
    it already (innovation_covariance of these P, H, R: a gate computed it), else computed
    here. Where S is singular or the result not finite, `ok` is False and x, P are the prior's
    (guarded)."""
    PHt = P @ H.swapaxes(-1, -2)
    if S is None:
        S = H @ PHt + R
    S_inv = inverse(S)
    K = PHt @ S_inv
    x_new = x + (K @ y[..., None])[..., 0]
    joseph = identity(x.shape[-1]) - K @ H
    P_new = joseph @ P @ joseph.swapaxes(-1, -2) + K @ R @ K.swapaxes(-1, -2)
    # finite where x and P are: a NaN or an infinity makes their sum so (finite entries overflow it
    # only beyond 1e308, a result no filter keeps); one test instead of one per array
    ok = np.isfinite(x_new.sum(axis=-1) + P_new.sum(axis=(-2, -1)))
    if not ok.all():
        x_new = np.where(ok[..., None], x_new, x)
        P_new = np.where(ok[..., None, None], P_new, P)
    return Update(x_new, P_new, S, S_inv, K, ok)


class DiagonalUpdate(NamedTuple):
    """What diagonal_update computes: the posterior x, P, the NIS y^T S^-1 y (NaN where skipped)
    and `ok` (...,), False where the update is not finite (x, P then keep the prior)."""

    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray
    ok: np.ndarray


def diagonal_update(x: np.ndarray, P: np.ndarray, y: np.ndarray, H: np.ndarray, r: np.ndarray) -> DiagonalUpdate:
    """The Kalman measurement update of joseph_update for a diagonal R = diag(r), r (..., m) the
    variances (> 0; a padded row with H = 0, y = 0 and r = 1 changes nothing), in information form
    (module docstring): P+ = (P^-1 + H^T R^-1 H)^-1, computed as the solution of
    (I + P H^T R^-1 H) P+ = P (no inverse of P, which may be singular) and symmetrised,
    x+ = x + P+ H^T R^-1 y,
    NIS = y^T R^-1 e with the post-fit residual e = y - H (x+ - x) (= R S^-1 y). Mathematically
    the same as joseph_update (equal to rounding, tests/test_filter_numerics.py); it solves one
    n x n system instead of inverting the m x m S, which for a bank's padded epochs (m up to a
    few dozen, n = 4) is most of the cost. Where the result is not finite, that batch entry falls
    back to joseph_update (same guards: ok False only where it too is not finite)."""
    HtRinv = np.swapaxes(H, -1, -2) / r[..., None, :]
    try:                                          # (P^-1 + A)^-1 = (I + P A)^-1 P: one solve, no P^-1
        P_new = np.linalg.solve(np.eye(x.shape[-1]) + P @ (HtRinv @ H), P)
        P_new = 0.5 * (P_new + np.swapaxes(P_new, -1, -2))          # symmetric as a covariance is
    except np.linalg.LinAlgError:
        P_new = np.full(np.broadcast_shapes(P.shape, HtRinv.shape[:-2] + P.shape[-2:]), np.nan)
    step = (P_new @ (HtRinv @ y[..., None]))[..., 0]                 # K y, K = P+ H^T R^-1
    x_new = x + step
    e = y - (H @ step[..., None])[..., 0]
    nis_new = (y * e / r).sum(axis=-1)
    ok = np.isfinite(x_new).all(axis=-1) & np.isfinite(P_new).all(axis=(-2, -1)) & np.isfinite(nis_new)
    if not ok.all():                              # rare: the covariance form decides these entries
        full = joseph_update(x, P, y, H, r[..., None] * np.eye(r.shape[-1]))
        x_new = np.where(ok[..., None], x_new, full.x)
        P_new = np.where(ok[..., None, None], P_new, full.P)
        nis_new = np.where(ok, nis_new, np.where(full.ok, nis(y, full.S_inv), np.nan))
        ok = ok | full.ok
    return DiagonalUpdate(x_new, P_new, nis_new, ok)


def nis(y: np.ndarray, S_inv: np.ndarray) -> np.ndarray:
    """Normalised innovation squared y^T S^-1 y (...,) of innovations y (..., m)."""
    return (y[..., None, :] @ S_inv @ y[..., None])[..., 0, 0]


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
        self.guards = guards if guards is not None else Guards()

    def predict(self, F=None, Q=None, u=None, B=None) -> None:
        """x <- F x (+ B u), P <- F P F^T + Q (predict); F and Q default to the filter's own (a
        step of another length passes its own matrices)."""
        F = self.F if F is None else F
        Q = self.Q if Q is None else Q
        self.x, self.P = predict(self.x, self.P, F, Q, None if u is None else B @ u)

    def update(self, z, H=None, R=None, hx=None, S=None) -> None:
        """Measurement update (joseph_update); `hx` is the predicted measurement h(x) of a
        linearised model (default H x); S = H P H^T + R when the caller computed it (a gate).
        The measurement size may change from call to call."""
        H = self.H if H is None else H
        R = self.R if R is None else R
        y = z - (H @ self.x if hx is None else hx)
        new = joseph_update(self.x, self.P, y, H, R, S)
        if not new.ok:
            self.guards.skipped += 1
            return
        self.y, self.S, self.K, self.x, self.P, self._S_inv = y, new.S, new.K, new.x, new.P, new.S_inv

    @property
    def nis(self) -> float:
        """Normalised innovation squared y^T S^-1 y of the last update (NaN before any)."""
        return float("nan") if self._S_inv is None else float(nis(self.y, self._S_inv))


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
        """Update with a measurement model object (z, R() and linearise(x) -> (h(x), H), or h(x)
        and jacobian(x) for a model without linearise)."""
        hx, H = model.linearise(self.x) if hasattr(model, "linearise") else (model.h(self.x), model.jacobian(self.x))
        self.update(model.z, H=H, R=model.R(), hx=hx)
