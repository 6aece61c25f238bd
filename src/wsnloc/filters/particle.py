"""Bootstrap particle filter, vectorised over the particles, with systematic resampling.

N particles X_i (n,) with normalised weights w_i, started from N(x0, P0).
predict:  X_i <- F X_i (+ B u) + q_i,  q_i = S e_i,  e_i ~ N(0, I),  S = V diag(sqrt(max(lambda, 0)))
          from the eigen-decomposition Q = V diag(lambda) V^T (so a singular Q, e.g. the
          rank-2 constant-velocity noise, is fine)
update:   log w_i <- log w_i + sum_j log p(z_j | X_i),  then normalised with log-sum-exp;
          per element j, r_ij = z_j - h_j(X_i), sigma_j^2 = R_jj (a non-diagonal R, the correlated
          TDOA noise: the residuals whitened by R = L L^T, r_i <- L^-1 r_i, sigma_j = 1, log det L
          subtracted; Gaussian, no outlier component):
            Gaussian:        p = N(r_ij; 0, sigma_j^2)
            range elements with outlier_probability eps > 0 (Gaussian + uniform outlier mixture):
                             p = (1 - eps) N(r_ij; 0, sigma_j^2) + eps / span     (span in m)
          computed with logaddexp, so products of many small likelihoods never underflow.
          log_likelihood = log sum_i w_i(prior) p(z | X_i), the measurement's marginal likelihood.
resample: systematic, when ESS = 1 / sum w_i^2 < resample_threshold * N:
          positions u_k = (U + k) / N, U ~ U[0, 1), k = 0..N-1; particle k copies X_j with the
          smallest j whose cumulative weight exceeds u_k; weights reset to 1 / N; then each
          particle is moved by the shrunk Gaussian kernel of Liu & West (2001):
            X_k <- a X_k + (1 - a) x + h L e_k,  e_k ~ N(0, I),  a = sqrt(1 - h^2),
          x, L L^T = P the weighted mean and covariance before resampling and
          h = (4 / (N (n + 2)))^(1 / (n + 4)) (the Gaussian kernel's optimal bandwidth, as in
          the regularised particle filter of Musso, Oudjane & Le Gland 2001); the shrinkage
          keeps the cloud's mean and covariance (a^2 P + h^2 P = P) while refreshing it.
          Without it, measurements milliseconds apart (a ranging round's anchors, each at its
          own time) resample again and again with almost no process noise in between, and
          the cloud collapses onto a few copies of one particle that cannot follow the target.
x = sum w_i X_i,  P = sum w_i (X_i - x)(X_i - x)^T.
NIS of an update: y^T S^-1 y with y = z - sum w_i h(X_i), S = weighted covariance of h(X_i) + R
(prior weights), as for a Gaussian filter.
Collapse: a cloud that has left the target (started from a bad fix, or diverged) sees every
measurement far in the tail of its predictive density: exp(-NIS / 2), the measurement's
effective likelihood relative to a zero innovation, collapses. An update is a miss when
NIS / m > COLLAPSE_NIS_PER_DOF (beyond 5 sigma per element); when more than half of the last
COLLAPSE_WINDOW updates missed, the filter is `lost`: the loop's deleter drops it and the
initiator restarts it from a fresh fix (estimators.core), counted in guards.reinitialised.
Particles or weights that become non-finite skip the update (guards.skipped).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from wsnloc.filters.measurement_models import RangeModel
from wsnloc.filters.numerics import Guards, usable

LOG_2PI = np.log(2.0 * np.pi)
COLLAPSE_NIS_PER_DOF = 25.0     # (5 sigma)^2: a Gaussian innovation exceeds it with probability 6e-7
COLLAPSE_WINDOW = 10            # updates over which the misses are counted


def noise_square_root(Q) -> np.ndarray:
    """S with S S^T = Q for a symmetric positive semi-definite Q (eigen-decomposition;
    tiny negative eigenvalues from round-off are clipped to 0)."""
    lam, V = np.linalg.eigh(np.asarray(Q, dtype=float))
    return V * np.sqrt(np.maximum(lam, 0.0))


def log_sum_exp(a) -> float:
    """log sum_i exp(a_i) of a (N,), shifted by its maximum M so that no term overflows:
    M + log k + log1p(s / k), k = number of a_i equal to M, s = sum of exp(a_i - M) over the
    others (scipy.special.logsumexp's formula, accurate when one term dominates); +-inf or nan
    when M is."""
    m = np.max(a)
    if not np.isfinite(m):
        return float(m)
    at_max = a == m
    terms = np.exp(a - m)
    terms[at_max] = 0.0
    count = np.count_nonzero(at_max)
    return float(np.log1p(np.sum(terms) / count) + np.log(count) + m)


def systematic_resample(weights, rng: np.random.Generator) -> np.ndarray:
    """Indices (N,) of the particles kept by systematic resampling of normalised weights (N,)."""
    n = len(weights)
    positions = (rng.random() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0                                   # guard against round-off below 1
    return np.searchsorted(cumulative, positions, side="right")


def range_elements(model) -> np.ndarray:
    """Boolean mask (m,) of the measurement elements that are ranges (RangeModel parts)."""
    parts = getattr(model, "parts", [model])
    return np.concatenate([np.full(len(p.R()), isinstance(p, RangeModel)) for p in parts])   # rows of each part


def element_log_likelihoods(residuals, variances, heavy_tailed, outlier_probability: float,
                            outlier_span_m: float) -> np.ndarray:
    """log p of residuals r (N, m) with variances (m,): Gaussian, and on the columns where
    heavy_tailed (m,) is True the mixture (1 - eps) N(r; 0, var) + eps / span."""
    log_p = -0.5 * (residuals**2 / variances + np.log(variances) + LOG_2PI)
    if np.any(heavy_tailed):
        log_p[:, heavy_tailed] = np.logaddexp(np.log1p(-outlier_probability) + log_p[:, heavy_tailed],
                                              np.log(outlier_probability / outlier_span_m))
    return log_p


class ParticleFilter:
    """Bootstrap particle filter; `rng` (numpy.random.Generator) makes it reproducible.

    resample_threshold: resample when ESS < threshold * N (0..1); outlier_probability eps and
    outlier_span_m (m) set the heavy-tailed range likelihood (eps = 0: pure Gaussian).
    """

    def __init__(self, x, P, n_particles: int, rng: np.random.Generator, resample_threshold: float = 0.5,
                 outlier_probability: float = 0.0, outlier_span_m: float = 50.0, guards: Guards | None = None):
        if n_particles < 1:
            raise ValueError(f"particle filter n_particles must be >= 1, got {n_particles}")
        if not 0.0 <= resample_threshold <= 1.0:
            raise ValueError(f"particle filter resample_threshold must be in [0, 1], got {resample_threshold}")
        if not 0.0 <= outlier_probability < 1.0:
            raise ValueError(f"particle filter outlier_probability must be in [0, 1), got {outlier_probability}")
        if outlier_span_m <= 0:
            raise ValueError(f"particle filter outlier_span_m must be > 0, got {outlier_span_m}")
        self.rng = rng
        self.resample_threshold = resample_threshold
        self.outlier_probability = outlier_probability
        self.outlier_span_m = outlier_span_m
        x = np.asarray(x, dtype=float)
        self.particles = x + rng.standard_normal((n_particles, len(x))) @ noise_square_root(P).T
        self.log_weights = np.full(n_particles, -np.log(n_particles))
        self.log_likelihood = float("nan")
        self.nis = float("nan")
        self.resampled = False
        self.guards = guards if guards is not None else Guards()
        self.misses: deque = deque(maxlen=COLLAPSE_WINDOW)
        self.lost = False

    @property
    def weights(self) -> np.ndarray:
        return np.exp(self.log_weights)

    @property
    def x(self) -> np.ndarray:
        return self.weights @ self.particles

    @property
    def P(self) -> np.ndarray:
        d = self.particles - self.x
        return (self.weights[:, None] * d).T @ d

    @property
    def ess(self) -> float:
        """Effective sample size 1 / sum w_i^2."""
        return float(1.0 / np.sum(self.weights**2))

    def predict(self, F, Q, u=None, B=None) -> None:
        """Propagate every particle: X <- X F^T (+ u^T B^T) + noise drawn from Q."""
        X = self.particles @ F.T
        if u is not None:
            X = X + B @ u
        self.particles = X + self.rng.standard_normal(X.shape) @ noise_square_root(Q).T

    def update_model(self, model) -> None:
        """Weight the particles by p(z | X_i), then resample if the ESS fell below the threshold."""
        R = np.asarray(model.R())
        variances = np.diag(R)
        w = self.weights
        residuals = model.z - model.h_many(self.particles)           # (N, m)
        y = w @ residuals                                              # z - sum w_i h(X_i)
        spread = residuals - y
        heavy_tailed = range_elements(model) if self.outlier_probability > 0 else np.zeros(len(y), dtype=bool)
        log_det = 0.0
        if np.any(R != np.diag(variances)):        # correlated noise (TDOA): whitened residuals L^-1 r, R = L L^T
            L = np.linalg.cholesky(R)
            residuals, variances, log_det = np.linalg.solve(L, residuals.T).T, np.ones(len(y)), np.log(np.diag(L)).sum()
            heavy_tailed = np.zeros(len(y), dtype=bool)
        log_p = element_log_likelihoods(residuals, variances, heavy_tailed,
                                        self.outlier_probability, self.outlier_span_m)
        joint = self.log_weights + log_p.sum(axis=1) - log_det
        log_likelihood = log_sum_exp(joint)
        if not (usable(y) and np.isfinite(log_likelihood)):
            self.guards.skipped += 1
            return
        self.nis = float(y @ np.linalg.solve((w[:, None] * spread).T @ spread + R, y))
        self.log_likelihood = log_likelihood
        self.log_weights = joint - self.log_likelihood
        self.misses.append(self.nis > COLLAPSE_NIS_PER_DOF * len(y))
        if len(self.misses) == COLLAPSE_WINDOW and 2 * sum(self.misses) > COLLAPSE_WINDOW:
            self.lost = True
            self.guards.reinitialised += 1
        self.resampled = self.ess < self.resample_threshold * len(self.particles)
        if self.resampled:
            n, dim = self.particles.shape
            h = (4.0 / (n * (dim + 2))) ** (1.0 / (dim + 4))
            mean, kernel = self.x, h * noise_square_root(self.P)
            kept = self.particles[systematic_resample(self.weights, self.rng)]
            self.particles = np.sqrt(1.0 - h**2) * kept + (1.0 - np.sqrt(1.0 - h**2)) * mean \
                + self.rng.standard_normal(kept.shape) @ kernel.T
            self.log_weights = np.full(n, -np.log(n))
