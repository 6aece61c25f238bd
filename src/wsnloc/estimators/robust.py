"""Innovation gating and robust (M-estimator) measurement updates of a Kalman filter.

Both work on the linearised update of one measurement vector: predicted measurement
h(x-), Jacobian H, noise covariance R, measured z, prior x-, P-.

Gating (per measurement, chi-square with 1 degree of freedom): with the innovation
  y = z - h(x-) and its covariance S = H P- H^T + R, measurement i is rejected when
  d_i^2 = y_i^2 / S_ii > chi2_1^-1(probability),
so a correct measurement is rejected with probability 1 - `probability` (e.g. 0.999:
d_i > 3.29 sigma). Each measurement is tested alone, so one wild range of a burst does
not take the good ones with it; batch (epoch) and sequential updates share the test.

Robust update (iteratively reweighted R): the update minimises
  sum_i rho(r_i) + (x - x-)^T P-^-1 (x - x-),   r_i = (z_i - h_i(x)) / sigma_i,
with sigma_i^2 = R_ii. Its fixed point is a Kalman update with R_ii / w(r_i), the weight
w(r) = psi(r) / r of the loss, evaluated at the current estimate; starting from the prior
(r_i = y_i / sigma_i) the update is repeated until the weights settle (at most
`ROBUST_ITERATIONS`). Losses, with r in units of sigma:
- huber: rho = r^2/2 for |r| <= c, c|r| - c^2/2 beyond; w = min(1, c/|r|). The default
  c = 1.345 gives 95% efficiency at the Gaussian (Huber 1964; Holland & Welsch 1977):
  almost nothing lost on clean ranges, while an outlier's pull grows only linearly.
  With every |r_i| <= c all weights are 1 and the update is the plain Kalman update.
- cauchy: rho = c^2/2 log(1 + (r/c)^2); w = 1 / (1 + (r/c)^2). Redescending: a range
  10 sigma off gets weight ~0.05 with the default c = 2.385, again 95% efficiency at
  the Gaussian; suited to reflections (Cricket ultrasound, NLOS UWB), where the outliers
  are large and frequent. It is not convex: start from a good prior (the gate helps).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from statistics import NormalDist

import numpy as np

from wsnloc.filters.kalman import innovation_covariance

LOSSES = ("none", "huber", "cauchy")
DEFAULT_TUNING = {"huber": 1.345, "cauchy": 2.385}
ROBUST_ITERATIONS = 10
WEIGHT_TOLERANCE = 1e-6


@lru_cache(maxsize=None)
def gate_threshold(probability: float) -> float:
    """chi2_1^-1(probability): the largest accepted squared normalised innovation d_i^2,
    = Phi^-1((1 + probability) / 2)^2 (a chi-square variable of 1 dof is a squared standard
    normal; the standard library's normal quantile, so a gated job loads no scipy)."""
    return NormalDist().inv_cdf(0.5 * (1.0 + probability)) ** 2


def gate(y: np.ndarray, S: np.ndarray, probability: float) -> np.ndarray:
    """Boolean mask of the measurements kept: y_i^2 / S_ii <= chi2_1^-1(probability)."""
    return y**2 / np.diag(S) <= gate_threshold(probability)


def weights(r: np.ndarray, loss: str, c: float) -> np.ndarray:
    """M-estimator weights w(r) = psi(r) / r of normalised residuals r (units of sigma)."""
    a = np.abs(r)
    if loss == "huber":
        return np.where(a <= c, 1.0, c / np.maximum(a, 1e-300))
    if loss == "cauchy":
        return 1.0 / (1.0 + (r / c) ** 2)
    if loss == "none":
        return np.ones_like(r)
    raise ValueError(f"unknown robust loss {loss!r} (known: {', '.join(LOSSES)})")


@dataclass(frozen=True)
class UpdateOptions:
    """gate_probability: 0 = no gate; loss 'none' = plain update; c = loss tuning constant (sigma)."""

    gate_probability: float = 0.0
    loss: str = "none"
    c: float = 1.345


def robust_update(filt, z: np.ndarray, H: np.ndarray, R: np.ndarray, hx: np.ndarray,
                  options: UpdateOptions, S: np.ndarray | None = None) -> np.ndarray:
    """Gate, then update `filt` (a KalmanFilter: x, P, update(z, H, R, hx, S)) with the kept
    measurements, reweighting R by the loss. S: the prior's S = H P- H^T + R when the caller
    has it (filters.kalman.innovation_covariance; else computed where needed), shared by the
    gate and the plain update. Returns the mask of the measurements used; with none kept the filter
    is left unchanged."""
    keep = np.ones(len(z), dtype=bool)
    if options.gate_probability > 0.0:
        S = innovation_covariance(filt.P, H, R) if S is None else S
        keep = gate(z - hx, S, options.gate_probability)
    if not keep.any():
        return keep
    if not keep.all():
        index = np.ix_(keep, keep)
        z, H, R, hx, S = z[keep], H[keep], R[index], hx[keep], None if S is None else S[index]
    if options.loss == "none":
        filt.update(z, H=H, R=R, hx=hx, S=S)
        return keep
    x0, P0 = filt.x.copy(), filt.P.copy()
    sigma = np.sqrt(np.diag(R))
    w = weights((z - hx) / sigma, options.loss, options.c)
    for _ in range(ROBUST_ITERATIONS):
        filt.x, filt.P = x0.copy(), P0.copy()
        filt.update(z, H=H, R=R / np.sqrt(np.outer(w, w)), hx=hx)
        # residual at the new estimate, from the linearisation at the prior
        w_new = weights((z - hx - H @ (filt.x - x0)) / sigma, options.loss, options.c)
        if np.max(np.abs(w_new - w)) < WEIGHT_TOLERANCE:
            break
        w = w_new
    return keep
