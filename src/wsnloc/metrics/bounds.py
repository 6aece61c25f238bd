"""Cramer-Rao bounds: static CRLB / GDOP maps and the posterior CRB of a tracking filter.

Static, at a point p = (x, y) (m), anchors a_i, d_i = ||p - a_i|| (floored at 1 mm):
- TOA range with noise sigma_i (m), optionally 3-D with a known height difference dz_i
  (r_i = sqrt(d_i^2 + dz_i^2), as RangeModel):  g_i = dr_i/dp = (p - a_i) / r_i
- RSS, log-normal shadowing with exponent n and sigma_dB (as RssModel):
                                 g_i = dP_i/dp = -10 n / ln10 (p - a_i) / d_i^2
- Fisher information J(p) = sum_i g_i g_i^T / sigma_i^2 (2 x 2); hybrid = J_TOA + J_RSS.
- Position bound (m): sqrt(trace(J^-1)), a lower bound on the RMSE of any unbiased estimator;
  infinite where J is singular (fewer than two anchors, or all in line with the point).
- TDOA (pairs of receivers, correlated noise, TdoaModel): J = H^T R^-1 H (tdoa_crlb, tdoa_gdop).
- TOA GDOP = sqrt(trace((G^T G)^-1)), G rows g_i (unit vectors for 2-D ranges), i.e. the TOA
  bound with sigma = 1 m: CRLB = sigma GDOP for equal sigmas.
The 2 x 2 information matrices are kept as their three unique entries (Jxx, Jxy, Jyy) in the
last axis, so grids and anchor subsets combine by sums and matrix products.

Dynamic: the posterior CRB (Tichavsky, Muravchik, Nehorai 1998) of a state x_k with linear-
Gaussian motion x_{k+1} = F_k x_k (+ B u_k, a known input that does not change the bound)
+ w_k, w_k ~ N(0, Q_k), and additive-Gaussian measurements z_k = h_k(x_k) + v_k, v_k ~ N(0, R_k).
"""

from __future__ import annotations

import numpy as np

from wsnloc.filters.measurement_models import MIN_DISTANCE, TdoaModel

LN10 = np.log(10.0)


def _offsets(points, anchors):
    """(P, N, 2) offsets p - a_i and (P, N) planar distances d_i (m), floored at 1 mm."""
    diff = np.asarray(points, dtype=float)[:, None, :2] - np.asarray(anchors, dtype=float)[None, :, :2]
    return diff, np.maximum(np.hypot(diff[..., 0], diff[..., 1]), MIN_DISTANCE)


def _outer_entries(g, sigma):
    """(Jxx, Jxy, Jyy) of g g^T / sigma^2 for gradients g (P, N, 2): shape (P, N, 3)."""
    w = 1.0 / np.broadcast_to(np.asarray(sigma, dtype=float), g.shape[1:2]) ** 2
    gx, gy = g[..., 0], g[..., 1]
    return np.stack([gx * gx * w, gx * gy * w, gy * gy * w], axis=-1)


def toa_information_terms(points, anchors, sigma_m, dz_m=None) -> np.ndarray:
    """Per-anchor TOA Fisher information (P, N, 3) at points (P, 2), anchors (N, 2).

    sigma_m: range noise std (m), scalar or (N,); dz_m: anchor height - tag height (m), (N,),
    None for 2-D ranges. J_i = g_i g_i^T / sigma_i^2 with g_i = (p - a_i) / sqrt(d_i^2 + dz_i^2).
    """
    diff, d = _offsets(points, anchors)
    r = d if dz_m is None else np.sqrt(d**2 + np.asarray(dz_m, dtype=float)[None, :] ** 2)
    return _outer_entries(diff / r[..., None], sigma_m)


def rss_information_terms(points, anchors, exponent: float, sigma_db) -> np.ndarray:
    """Per-anchor RSS Fisher information (P, N, 3), in 1/m^2.

    Log-normal shadowing P_i = P0 - 10 n log10(d_i / d0) + v, v ~ N(0, sigma_dB^2):
    g_i = -10 n / ln10 (p - a_i) / d_i^2 (dB/m), J_i = g_i g_i^T / sigma_dB^2.
    """
    diff, d = _offsets(points, anchors)
    return _outer_entries(-10.0 * exponent / LN10 * diff / (d**2)[..., None], sigma_db)


def position_bound(information) -> np.ndarray:
    """sqrt(trace(J^-1)) (m) of 2 x 2 informations given as (..., 3) entries (Jxx, Jxy, Jyy).

    Closed form: trace(J^-1) = (Jxx + Jyy) / (Jxx Jyy - Jxy^2). Infinite where J is singular
    (determinant below 1e-12 of its scale squared).
    """
    jxx, jxy, jyy = np.moveaxis(np.asarray(information, dtype=float), -1, 0)
    det = jxx * jyy - jxy**2
    singular = det <= 1e-12 * (jxx + jyy) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.sqrt((jxx + jyy) / det)
    return np.where(singular, np.inf, bound)


def toa_crlb(points, anchors, sigma_m, dz_m=None) -> np.ndarray:
    """TOA position bound sqrt(trace(J^-1)) (m) at each point (P,)."""
    return position_bound(toa_information_terms(points, anchors, sigma_m, dz_m).sum(axis=1))


def rss_crlb(points, anchors, exponent: float, sigma_db) -> np.ndarray:
    """RSS position bound (m) at each point (P,)."""
    return position_bound(rss_information_terms(points, anchors, exponent, sigma_db).sum(axis=1))


def hybrid_crlb(points, toa_anchors, sigma_m, rss_anchors, exponent: float, sigma_db, dz_m=None) -> np.ndarray:
    """Hybrid TOA + RSS position bound (m): the two informations add (independent noises)."""
    information = (toa_information_terms(points, toa_anchors, sigma_m, dz_m).sum(axis=1)
                   + rss_information_terms(points, rss_anchors, exponent, sigma_db).sum(axis=1))
    return position_bound(information)


def gdop(points, anchors, dz_m=None) -> np.ndarray:
    """TOA geometric dilution of precision sqrt(trace((G^T G)^-1)) (dimensionless) at each point."""
    return toa_crlb(points, anchors, 1.0, dz_m)


def tdoa_crlb(points, receivers, pairs, sigma_m, dz_m=None) -> np.ndarray:
    """TDOA position bound sqrt(trace(J^-1)) (m) at each point (P,): J = H^T R^-1 H of the pairs
    (receiver, reference) = receivers[pairs[i]] (TdoaModel: h_i = r_a - r_b, R = D diag(sigma^2) D^T,
    sigma_m the arrival noise of each receiver, m; dz_m their heights above the tag, None in 2-D)."""
    model = TdoaModel(np.asarray(receivers, dtype=float)[:, :2], np.asarray(pairs, dtype=np.intp), sigma_m,
                      None if dz_m is None else np.asarray(dz_m, dtype=float))
    R_inv = np.linalg.inv(model.R())
    information = []
    for point in np.asarray(points, dtype=float):
        H = model.jacobian(point[:2])
        J = H.T @ R_inv @ H
        information.append((J[0, 0], J[0, 1], J[1, 1]))
    return position_bound(np.array(information).reshape(-1, 3))


def tdoa_gdop(points, receivers, pairs, dz_m=None) -> np.ndarray:
    """TDOA GDOP (dimensionless): tdoa_crlb with 1 m arrival noise, so CRLB = sigma GDOP. With
    receivers close together and the tag far away it grows with the distance squared over the
    aperture: the range differences fix the bearing and hardly the distance."""
    return tdoa_crlb(points, receivers, pairs, 1.0, dz_m)


def grid_points(width_m: float, height_m: float, spacing_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cell centres of a floor grid: x (nx,), y (ny,) and the points (ny * nx, 2), x varying
    fastest (values over the points reshape to (ny, nx))."""
    x = np.arange(spacing_m / 2.0, width_m, spacing_m)
    y = np.arange(spacing_m / 2.0, height_m, spacing_m)
    xx, yy = np.meshgrid(x, y)
    return x, y, np.column_stack([xx.ravel(), yy.ravel()])


def to_matrices(information, state_dim: int = 2) -> np.ndarray:
    """(..., 3) position informations as (..., n, n) state informations (zero outside the
    position block [x, y] = state entries 0 and 1; range and RSS do not observe the rest)."""
    information = np.asarray(information, dtype=float)
    out = np.zeros(information.shape[:-1] + (state_dim, state_dim))
    out[..., 0, 0] = information[..., 0]
    out[..., 0, 1] = out[..., 1, 0] = information[..., 1]
    out[..., 1, 1] = information[..., 2]
    return out


def available_information(terms, available) -> np.ndarray:
    """Measurement information of each step from the anchors heard at that step.

    terms: (..., K, N, 3) per-anchor information at the true position of each step (one
    trajectory, or one per Monte Carlo run); available: (..., K, N) booleans (one row of
    steps per run). Returns (..., K, 3): the sum over the available anchors.
    """
    return np.einsum("...kn,...knc->...kc", np.asarray(available, dtype=float), np.asarray(terms, dtype=float))


def model_information(model, states) -> np.ndarray:
    """H^T R^-1 H (K, n, n) of a measurement model (RangeModel, RssModel, Stacked: `jacobian`,
    `R`) evaluated at each true state (K, n); for models not covered by the vectorised terms."""
    states = np.atleast_2d(np.asarray(states, dtype=float))
    R_inv = np.linalg.inv(model.R())
    out = np.empty((len(states), states.shape[1], states.shape[1]))
    for k, x in enumerate(states):
        H = model.jacobian(x)
        out[k] = H.T @ R_inv @ H
    return out


def pcrb(P0, F, Q, information) -> np.ndarray:
    """Posterior CRB covariances (..., K, n, n) along a true trajectory.

    P0: prior covariance of x_0 (n, n), i.e. J_0^- = P0^-1 before the first measurement.
    F, Q: transition and process noise, (n, n) for every step or (..., K - 1, n, n), entry
      k - 1 taking step k - 1 to step k (leading axes: one sequence per batch entry).
    information: (..., K, n, n) measurement information I_k = H_k^T R_k^-1 H_k at the true
      state (H_k the Jacobian of the measurements available at step k; zero when none);
      leading axes (e.g. Monte Carlo runs, each with its own measurement availability) are
      evaluated independently in one batch.
    Recursion (Tichavsky et al. 1998, eq. 21, rewritten with the matrix inversion lemma):
        J_0 = P0^-1 + I_0,   J_{k+1} = (Q_k + F_k J_k^-1 F_k^T)^-1 + I_{k+1}.
    This covariance form is used instead of D22 - D21 (J_k + D11)^-1 D12 with
    D11 = F^T Q^-1 F, D12 = -F^T Q^-1, D22 = Q^-1 + I because it needs no Q^-1: the PV and
    PVA process noises are singular (rank 2 of 4 or 6) and Q = 0 is the static case. It needs
    F_k nonsingular and P0 positive definite (then the predicted covariance is too).
    The bound averaged over Monte Carlo runs is the mean of the per-run matrices over that
    axis (`.mean(axis=0)`), since each run has its own measurement availability.
    """
    information = np.asarray(information, dtype=float)
    K, n = information.shape[-3], information.shape[-1]
    steps = information.shape[:-3] + (max(K - 1, 0), n, n)
    F = np.broadcast_to(np.asarray(F, dtype=float), steps)
    Q = np.broadcast_to(np.asarray(Q, dtype=float), steps)
    bounds = np.empty(information.shape)
    predicted = np.broadcast_to(np.asarray(P0, dtype=float), information.shape[:-3] + (n, n))
    Ft = F.swapaxes(-1, -2)
    for k in range(K):
        if k:
            predicted = F[..., k - 1, :, :] @ bounds[..., k - 1, :, :] @ Ft[..., k - 1, :, :] + Q[..., k - 1, :, :]
        inverse = np.linalg.inv(np.linalg.inv(predicted) + information[..., k, :, :])
        bounds[..., k, :, :] = 0.5 * (inverse + inverse.swapaxes(-1, -2))   # symmetric to rounding
    return bounds


def position_rmse_bound(bounds, axes: int = 2) -> np.ndarray:
    """sqrt(P_xx + P_yy) (m) of bound covariances (..., n, n): the position RMSE bound; with
    axes = 3 (a 3-D state [x, y, z, ...]) sqrt(P_xx + P_yy + P_zz), the 3-D RMSE bound."""
    bounds = np.asarray(bounds)
    return np.sqrt(sum(bounds[..., i, i] for i in range(axes)))
