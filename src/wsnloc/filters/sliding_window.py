"""Sliding-window batch estimator: robust non-linear least squares over the last W seconds.

Unknowns: states s_j = [x, y, vx, vy] (m, m/s) at K knots tau_0 < ... < tau_K-1 = t_end spaced
knot_s apart and covering the window [t_end - window_s, t_end]. Whitened residuals (unit variance):
  constant-velocity prior between consecutive knots (white-noise acceleration, spectral density
  q = accel_sigma^2 in m^2/s^3), Delta = knot_s:
      L^-1 (s_j+1 - Phi s_j),  Phi = [[I, Delta I], [0, I]],
      L L^T = Qc = q [[Delta^3/3 I, Delta^2/2 I], [Delta^2/2 I, Delta I]]
      (the continuous-time form: positive definite, unlike the rank-2 piecewise-constant Q of
      motion_models.constant_velocity, which cannot be whitened)
  weak prior on the first knot from the previous window's solution, propagated to tau_0 and
  inflated:  L0^-1 (s_0 - s_prior),  L0 L0^T = prior_inflation (Phi Sigma Phi^T + Qc)
  one per range measured at time t to an anchor a with height difference dz, from the knot j
  before t (delta = t - tau_j):
      (sqrt(||p_j + delta v_j - a||^2 + dz^2) - r) / sigma
  or, for range differences (TDOA) r(a) - r(b) measured together (one group, correlated
  noise R_g = D diag(sigma^2) D^T as measurement_models.TdoaModel), the group's residuals
  whitened by R_g = L_g L_g^T:  L_g^-1 (h_g - z_g), h_i = r(a_i) - r(b_i)
Minimised with filters.least_squares (scipy.optimize.least_squares' trust-region algorithm
and robust-loss scaling, in numpy; ftol = xtol = gtol = 1e-12), warm-started from the
previous window; the robust loss rho (huber, soft_l1, cauchy or linear) acts on the range
residuals only, with f_scale in units of sigma (the priors stay Gaussian). Covariance of the
knots: (J^T J)^-1 with J the loss-weighted Jacobian at the solution; the estimate is the last
knot (x, P). On real data (filters.numerics, counted in `guards.regularised`): a J^T J that is
singular or whose inverse is not positive definite (ranges from too few anchors in the window,
a degenerate geometry) and a prior covariance that is not positive definite are regularised.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from wsnloc.filters.least_squares import LOSSES, robust_least_squares
from wsnloc.filters.measurement_models import MIN_DISTANCE
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.filters.numerics import Guards, regularise, safe_cholesky

STATE = 4


def white_noise_acceleration_cov(dt: float, accel_sigma: float) -> np.ndarray:
    """Qc (4, 4) of [x, y, vx, vy] over dt (s) for white acceleration of density accel_sigma^2 (m^2/s^3)."""
    block = accel_sigma**2 * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    return np.kron(block, np.eye(2))


class RangeFactors(NamedTuple):
    """The window's ranges, each tied to the knot before it: knot (k,) index, delta (k,) s
    after that knot, anchors (k, 2) m, dz (k,) m, ranges (k,) m, sigma (k,) m; for range
    differences also the reference anchors (k, 2) and their dz (k,) (NaN rows: plain ranges) and
    the whitening matrix W (k, k) (block-diagonal L_g^-1; None: diag(1 / sigma))."""
    knot: np.ndarray
    delta: np.ndarray
    anchors: np.ndarray
    dz: np.ndarray
    ranges: np.ndarray
    sigma: np.ndarray
    ref: np.ndarray | None = None
    ref_dz: np.ndarray | None = None
    whiten: np.ndarray | None = None


class WindowEstimate(NamedTuple):
    x: np.ndarray          # (4,) [x, y, vx, vy] at the window's end (m, m/s)
    P: np.ndarray          # (4, 4) its covariance
    n_ranges: int


class SlidingWindowEstimator:
    """Call estimate() once per output time, with increasing t_end."""

    def __init__(self, window_s: float = 2.0, knot_s: float = 0.5, accel_sigma: float = 0.5,
                 loss: str = "huber", f_scale: float = 1.345, prior_inflation: float = 10.0,
                 guards: Guards | None = None):
        if loss not in LOSSES:
            raise ValueError(f"sliding window loss must be one of {sorted(LOSSES)}, got {loss!r}")
        for name, value in (("window_s", window_s), ("knot_s", knot_s), ("accel_sigma", accel_sigma),
                            ("f_scale", f_scale), ("prior_inflation", prior_inflation)):
            if not value > 0:
                raise ValueError(f"sliding window {name} must be > 0, got {value}")
        if knot_s > window_s:
            raise ValueError(f"sliding window knot_s ({knot_s}) must not exceed window_s ({window_s})")
        self.window_s, self.knot_s, self.accel_sigma = window_s, knot_s, accel_sigma
        self.rho, self.f_scale, self.prior_inflation = LOSSES[loss], f_scale, prior_inflation
        self.n_knots = int(np.ceil(window_s / knot_s - 1e-9)) + 1
        self.Phi = constant_velocity(knot_s, accel_sigma)[0]
        self._W_cv = np.linalg.inv(np.linalg.cholesky(white_noise_acceleration_cov(knot_s, accel_sigma)))
        # Jacobian of the constant-velocity residuals W (s_j+1 - Phi s_j), j = 0..K-2: (4(K-1), 4K)
        self._J_cv = (np.kron(np.eye(self.n_knots - 1, self.n_knots, 1), self._W_cv)
                      - np.kron(np.eye(self.n_knots - 1, self.n_knots), self._W_cv @ self.Phi))
        self._previous = None      # (knot times (K,), states (K, 4), covariance (4K, 4K))
        self.guards = guards if guards is not None else Guards()

    def _propagate(self, times):
        """The previous solution carried to the given times by the constant-velocity model, each
        from the last previous knot at or before it: means Phi(dt) s_j (len(times), 4), and the
        covariance Phi Sigma_j Phi^T + Qc(dt) at times[0]."""
        knots, states, cov = self._previous
        j = np.searchsorted(knots, times + 1e-9, side="right") - 1
        if np.any(j < 0):
            raise ValueError("sliding window: t_end must increase from call to call")
        dt = times - knots[j]
        means = states[j].copy()
        means[:, :2] += dt[:, None] * states[j, 2:]
        F = constant_velocity(dt[0], self.accel_sigma)[0]
        block = cov[STATE * j[0]:STATE * (j[0] + 1), STATE * j[0]:STATE * (j[0] + 1)]
        return means, F @ block @ F.T + white_noise_acceleration_cov(dt[0], self.accel_sigma)

    def estimate(self, t_end, t, anchors_xy, dz_m, ranges_m, sigma_m, initial_state=None,
                 differences=None) -> WindowEstimate:
        """Solve the window ending at t_end (s) from the ranges measured in it.

        t (k,) s, each in [t_end - window_s, t_end]; anchors_xy (k, 2) m; dz_m (k,) anchor
        height - tag height (m, 0 for 2-D ranges); ranges_m (k,) m; sigma_m (k,) m, > 0.
        differences: for range differences r(a) - r(b) (ranges_m the measured differences),
        (reference anchors (k, 2) m, their dz (k,) m, whitening W (k, k) with W^T W = R^-1).
        initial_state (4,): starting guess for the first call (default: the anchors' centroid,
        at rest); later calls warm-start from, and put a weak prior on, the previous solution.
        """
        t = np.asarray(t, dtype=float)
        anchors_xy = np.asarray(anchors_xy, dtype=float).reshape(-1, 2)
        dz_m, ranges_m, sigma_m = (np.broadcast_to(np.asarray(a, dtype=float), t.shape)
                                   for a in (dz_m, ranges_m, sigma_m))
        if len(anchors_xy) != len(t):
            raise ValueError(f"sliding window: {len(t)} times but {len(anchors_xy)} anchor positions")
        if np.any(t < t_end - self.window_s - 1e-9) or np.any(t > t_end + 1e-9):
            raise ValueError(f"sliding window: measurement times must lie in [{t_end - self.window_s}, {t_end}]")
        if np.any(~(sigma_m > 0)):
            raise ValueError("sliding window: range sigmas must be > 0")
        knots = t_end - self.knot_s * np.arange(self.n_knots - 1, -1, -1)
        if self._previous is None:
            if len(t) < STATE:
                raise ValueError(f"sliding window: the first window needs at least {STATE} ranges, got {len(t)}")
            guess = (np.array([*anchors_xy.mean(axis=0), 0.0, 0.0]) if initial_state is None
                     else np.asarray(initial_state, dtype=float))
            start, prior = np.tile(guess, (self.n_knots, 1)), None
        else:
            start, first_cov = self._propagate(knots)
            prior = (start[0], np.linalg.inv(safe_cholesky(self.prior_inflation * first_cov, self.guards)))
        j = np.clip(np.floor((t - knots[0]) / self.knot_s + 1e-9).astype(int), 0, self.n_knots - 1)
        ranges = RangeFactors(j, t - knots[j], anchors_xy, dz_m, ranges_m, sigma_m, *(differences or ()))
        n_gaussian = STATE * (self.n_knots - 1) + (0 if prior is None else STATE)
        theta, J = self._solve(start.ravel(), prior, ranges, n_gaussian)
        cov = self._covariance(J)
        states = theta.reshape(self.n_knots, STATE)
        self._previous = (knots, states, cov)
        return WindowEstimate(states[-1].copy(), cov[-STATE:, -STATE:].copy(), len(t))

    def _covariance(self, J: np.ndarray) -> np.ndarray:
        """(J^T J)^-1, of regularise(J^T J) when J^T J is singular or its inverse not positive
        definite (counted)."""
        information = J.T @ J
        try:
            cov = np.linalg.inv(information)
            np.linalg.cholesky(cov)
            return cov
        except np.linalg.LinAlgError:
            self.guards.regularised += 1
            return np.linalg.inv(regularise(information))

    def _solve(self, start, prior, ranges, n_gaussian):
        """(theta, loss-weighted J at theta): the window's minimiser from start, the first
        n_gaussian residuals Gaussian."""
        solution = robust_least_squares(lambda theta: self._residuals(theta, prior, ranges),
                                        lambda theta: self._jacobian(theta, prior, ranges), start,
                                        self.rho, self.f_scale, n_gaussian, ftol=1e-12, xtol=1e-12, gtol=1e-12)
        return solution.x, solution.jac

    def _range_geometry(self, theta, ranges, anchors=None, dz=None):
        """(p - a, distance) of each factor's position at its time to `anchors` (default its anchor)."""
        s = theta.reshape(self.n_knots, STATE)[ranges.knot]
        diff = s[:, :2] + ranges.delta[:, None] * s[:, 2:] - (ranges.anchors if anchors is None else anchors)
        return diff, np.maximum(np.sqrt((diff**2).sum(axis=1) + (ranges.dz if dz is None else dz) ** 2), MIN_DISTANCE)

    def _measurement(self, theta, ranges):
        """(h (k,), dh/dp (k, 2)) of the factors: ranges, or range differences r(a) - r(b)."""
        diff, h = self._range_geometry(theta, ranges)
        gradient = diff / h[:, None]
        if ranges.ref is not None:
            ref_diff, ref_h = self._range_geometry(theta, ranges, ranges.ref, ranges.ref_dz)
            h, gradient = h - ref_h, gradient - ref_diff / ref_h[:, None]
        return h, gradient

    def _whiten(self, ranges, values):
        """Whitened rows: W values, or values / sigma without a whitening matrix."""
        if ranges.whiten is None:
            return values / (ranges.sigma if values.ndim == 1 else ranges.sigma[:, None])
        return ranges.whiten @ values

    def _residuals(self, theta, prior, ranges):
        s = theta.reshape(self.n_knots, STATE)
        parts = [] if prior is None else [prior[1] @ (s[0] - prior[0])]
        parts.append(((s[1:] - s[:-1] @ self.Phi.T) @ self._W_cv.T).ravel())
        h, _ = self._measurement(theta, ranges)
        parts.append(self._whiten(ranges, h - ranges.ranges))
        return np.concatenate(parts)

    def _jacobian(self, theta, prior, ranges):
        n_prior = 0 if prior is None else STATE
        n_gaussian = n_prior + len(self._J_cv)
        J = np.zeros((n_gaussian + len(ranges.knot), STATE * self.n_knots))
        if prior is not None:
            J[:STATE, :STATE] = prior[1]
        J[n_prior:n_gaussian] = self._J_cv
        _, gradient = self._measurement(theta, ranges)
        cols = STATE * ranges.knot[:, None] + np.arange(STATE)          # [x, y, vx, vy] of knot j
        rows = np.zeros((len(cols), J.shape[1]))
        rows[np.arange(len(cols))[:, None], cols] = np.hstack([gradient, ranges.delta[:, None] * gradient])
        J[n_gaussian:] = self._whiten(ranges, rows)
        return J
