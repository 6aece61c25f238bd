"""Filter consistency: NEES, NIS, their Monte Carlo averages and chi-square bands.

For a consistent filter (Bar-Shalom, Li, Kirubarajan 2001, sec. 5.4):
- NEES  eps_k = e_k^T P_k^-1 e_k, e_k = x_k - x_hat_k (state or position error), ~ chi2(n)
- NIS   nu_k = y_k^T S_k^-1 y_k, innovation y_k and its covariance S_k, ~ chi2(m_k), where the
  measurement size m_k may change from step to step.
- ANEES / ANIS at step k: the mean over the M_k runs with a value at k. Their sum is
  chi2(sum of dofs), so the two-sided 95% band is
      [chi2_{0.025}(D_k) / M_k, chi2_{0.975}(D_k) / M_k],  D_k = sum over runs of the dof
  (= M n for NEES of an n-dim state).
- Time-averaged ANEES: the mean over all M K values, band chi2_q(D) / (M K) with D the sum
  of all dofs (= M n K) when the values are independent in time. NEES is not: a filter's
  velocity error persists over many steps, and with that band a matched PV Kalman filter's
  full-state ANEES fell outside it in 3 of 5 seeds (tests/test_consistency.py). The runs
  are independent, so the spread of the per-run time averages measures the correlation:
  with z_r = (sum of run r's values) / D_r (D_r its dof sum; z_r ~ chi2(D_r / phi) phi / D_r),
      phi = max(1, sum_r D_r (z_r - z_bar)^2 / ((M - 1) 2 z_bar^2))   (1 for white values)
  and the band is phi chi2_q(D / phi) / (M K), i.e. chi2_q(M n K_eff) / (M K_eff) with
  K_eff = K / phi independent steps (a moment-matched, Satterthwaite-type approximation).
  With one run, phi = 1.
- Verdict from the time average: above the band "optimistic" (errors larger than the filter
  claims), below "pessimistic", inside "consistent".
chi2_q(D) = chdtri(D, 1 - q): scipy.special's inverse survival function of the chi-square
distribution (what scipy.stats.chi2.ppf evaluates; scipy.stats costs 0.2 s to import per job).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def normalized_squared(errors, covariances, components=None) -> np.ndarray:
    """e^T P^-1 e for errors (..., n) and covariances (..., n, n); NEES when e is the state
    error and P the filter covariance, NIS when e is the innovation and P its covariance S.

    components: state indices to keep (e.g. (0, 1) for the position-only NEES, using the
    position block of P); None keeps all. A singular P (a filter claiming certainty, e.g. a
    collapsed particle cloud) gives inf: any error is infinitely many of its sigmas.
    """
    e = np.asarray(errors, dtype=float)
    P = np.asarray(covariances, dtype=float)
    if components is not None:
        index = np.asarray(components)
        e = e[..., index]
        P = P[..., index[:, None], index[None, :]]
    singular = ~(np.linalg.det(P) > 0)
    safe = np.where(singular[..., None, None], np.eye(P.shape[-1]), P)
    value = np.einsum("...i,...i->...", e, np.linalg.solve(safe, e[..., None])[..., 0])
    return np.where(singular, np.inf, value)


def chi2_quantile(dof, probability) -> np.ndarray:
    """Quantile chi2_q(dof) of the chi-square distribution (vectorised over dof)."""
    from scipy.special import chdtri    # here: jobs that test no consistency load no scipy

    return chdtri(np.asarray(dof, dtype=float), 1.0 - probability)


def chi2_band(dof_sum, count, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided band of a mean of `count` chi-square values whose dofs sum to dof_sum:
    [chi2_{(1-c)/2}(dof_sum), chi2_{(1+c)/2}(dof_sum)] / count."""
    tail = (1.0 - confidence) / 2.0
    count = np.asarray(count, dtype=float)
    return chi2_quantile(dof_sum, tail) / count, chi2_quantile(dof_sum, 1.0 - tail) / count


@dataclass(frozen=True)
class ConsistencyTest:
    """Monte Carlo average of NEES or NIS over time with its bands and the verdict."""

    average: np.ndarray       # (K,) ANEES / ANIS at each step (NaN where no run has a value)
    low: np.ndarray           # (K,) lower end of the 95% band
    high: np.ndarray          # (K,) upper end
    time_average: float       # mean over all runs and steps
    time_low: float
    time_high: float
    inflation: float          # phi >= 1: variance inflation of the time average by correlation
    verdict: str              # consistent / optimistic / pessimistic

    @property
    def share_inside(self) -> float:
        """Share of the steps whose average lies inside its band."""
        ok = np.isfinite(self.average)
        return float(np.mean((self.average[ok] >= self.low[ok]) & (self.average[ok] <= self.high[ok])))


def verdict(value: float, low: float, high: float) -> str:
    """'optimistic' above the band, 'pessimistic' below it, else 'consistent'."""
    return "optimistic" if value > high else "pessimistic" if value < low else "consistent"


def consistency_test(values, dof, confidence: float = 0.95) -> ConsistencyTest:
    """ANEES / ANIS of values (M, K) (runs x steps, NaN where a run has no value, e.g. no
    update for NIS) with their per-value dofs: a scalar (state dim for NEES) or (M, K)
    (measurement dim of each update for NIS)."""
    values = np.asarray(values, dtype=float)
    if values.ndim != 2:
        raise ValueError(f"values must be (runs, steps), got shape {values.shape}")
    present = np.isfinite(values)
    dof = np.where(present, np.broadcast_to(np.asarray(dof, dtype=float), values.shape), 0.0)
    count = present.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        average = np.where(present, values, 0.0).sum(axis=0) / count
        low, high = chi2_band(dof.sum(axis=0), count, confidence)
    total = int(present.sum())
    time_average = float(values[present].mean())
    phi = time_correlation_inflation(np.where(present, values, 0.0).sum(axis=1), dof.sum(axis=1))
    time_low, time_high = (phi * float(v) for v in chi2_band(dof.sum() / phi, total, confidence))
    return ConsistencyTest(average, low, high, time_average, time_low, time_high, phi,
                           verdict(time_average, time_low, time_high))


def time_correlation_inflation(run_sums, run_dofs) -> float:
    """phi = max(1, sum_r D_r (z_r - z_bar)^2 / ((M - 1) 2 z_bar^2)), z_r = S_r / D_r, from
    each run's sum S_r of NEES / NIS values and the sum D_r of their dofs (runs with D_r = 0
    are skipped); 1 with fewer than two runs. Scale-free: an over- or under-confident filter
    (values c chi2) gives the same phi as a consistent one."""
    used = np.asarray(run_dofs, dtype=float) > 0
    S, D = np.asarray(run_sums, dtype=float)[used], np.asarray(run_dofs, dtype=float)[used]
    if len(D) < 2:
        return 1.0
    z = S / D
    return max(1.0, float(np.sum(D * (z - z.mean()) ** 2) / ((len(D) - 1) * 2.0 * z.mean() ** 2)))
