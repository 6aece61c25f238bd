"""Small dense robust non-linear least squares (trust-region Levenberg-Marquardt), in numpy.

Minimises  C(x) = 1/2 sum_i g_i(f_i(x))  over x (n,), residuals f (m,) with Jacobian J (m, n):
  g_i(f) = f^2 for the first `n_plain` residuals (Gaussian priors), and for the others
  g(f) = s^2 rho((f / s)^2) with the robust loss rho (LOSSES below) and its scale s = f_scale,
  as scipy.optimize.least_squares(loss=..., f_scale=s) does.
Robust residuals enter the Gauss-Newton model through Triggs' correction (scipy's
scale_for_robust_loss_function), with z = (f / s)^2 and rho', rho'' taken at z:
  w = max(rho' + 2 rho'' z, EPS)      f~ = rho' f / sqrt(w)      J~ = sqrt(w) J
so that J~^T f~ = grad C exactly and J~^T J~ approximates its Hessian.
Step (scipy's trf without bounds, x_scale 1, exact trust-region solver): the minimiser of the
model ||J~ dx + f~||^2 / 2 within ||dx|| <= Delta (the Gauss-Newton step, or a
Levenberg-Marquardt step (J~^T J~ + alpha I) dx = -J~^T f~ on the boundary), Delta_0 = ||x0||
(1 if 0); with the gain ratio q = (actual cost reduction) / (model's reduction): Delta <-
||dx|| / 4 if q < 0.25, 2 Delta if q > 0.75 and ||dx|| > 0.95 Delta; the step is taken when it
lowers the cost.
Stopping (scipy's semantics): gtol: ||J~^T f~||_inf < gtol; ftol: a step lowers the cost by
dC < ftol C with gain ratio > 0.25; xtol: ||dx|| < xtol (xtol + ||x||). Not stopped after
`max_iter` steps: ConvergenceError.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from wsnloc.errors import WsnlocError

EPS = np.finfo(float).eps


class ConvergenceError(WsnlocError):
    """The solver met none of its stopping tolerances within its iteration limit."""


def _linear(z):
    return np.vstack([z, np.ones_like(z), np.zeros_like(z)])


def _huber(z):
    big = z > 1.0
    root = np.sqrt(np.where(big, z, 1.0))
    return np.vstack([np.where(big, 2.0 * root - 1.0, z), np.where(big, 1.0 / root, 1.0),
                      np.where(big, -0.5 / root**3, 0.0)])


def _soft_l1(z):
    t = 1.0 + z
    return np.vstack([2.0 * (np.sqrt(t) - 1.0), t**-0.5, -0.5 * t**-1.5])


def _cauchy(z):
    t = 1.0 + z
    return np.vstack([np.log(t), 1.0 / t, -1.0 / t**2])


# rho(z) with z = (residual / f_scale)^2, and its first two derivatives (scipy's convention).
LOSSES = {"linear": _linear, "huber": _huber, "soft_l1": _soft_l1, "cauchy": _cauchy}


class Solution(NamedTuple):
    x: np.ndarray          # (n,) the minimiser
    cost: float            # C(x)
    jac: np.ndarray        # (m, n) J~ at x (loss-weighted: J~^T J~ is the Gauss-Newton Hessian)
    n_iter: int            # steps tried


class _Point(NamedTuple):
    """x with its cost C, loss-weighted residuals f~ and the robust rows' sqrt(w)."""
    x: np.ndarray
    cost: float
    f: np.ndarray
    sqrt_w: np.ndarray


def robust_least_squares(fun: Callable, jac: Callable, x0, rho: Callable = _linear, f_scale: float = 1.0,
                         n_plain: int = 0, ftol: float = 1e-8, xtol: float = 1e-8, gtol: float = 1e-8,
                         max_iter: int | None = None) -> Solution:
    """Minimise C(x) (module docstring) from x0; fun(x) -> f (m,), jac(x) -> J (m, n);
    rho: one of LOSSES, applied to the residuals from index n_plain on. max_iter: steps tried
    (one evaluation of fun each) before ConvergenceError; default 100 n, scipy's max_nfev."""
    point = _evaluate(fun, np.asarray(x0, dtype=float), rho, f_scale, n_plain)
    max_iter = 100 * len(point.x) if max_iter is None else max_iter
    J = _weighted_jacobian(jac(point.x), point, n_plain)
    radius, alpha = _norm(point.x) or 1.0, 0.0
    for n_iter in range(max_iter):
        g = J.T @ point.f
        if np.abs(g).max(initial=0.0) < gtol:
            return Solution(point.x, point.cost, J, n_iter)
        step = _gauss_newton_step(J, g, radius)
        if step is None:
            U, sv, Vt = np.linalg.svd(J, full_matrices=False)
            step, alpha = _trust_region_step(sv, Vt, sv * (U.T @ point.f), len(J), radius, alpha)
        else:
            alpha = 0.0
        Js = J @ step
        predicted = -(g @ step + 0.5 * (Js @ Js))
        trial = _evaluate(fun, point.x + step, rho, f_scale, n_plain)
        step_norm = _norm(step)
        reduction = point.cost - trial.cost if np.isfinite(trial.cost) else -np.inf
        ratio = reduction / predicted if predicted > 0 else float(predicted == reduction == 0)
        converged = ((reduction < ftol * point.cost and ratio > 0.25)
                     or step_norm < xtol * (xtol + _norm(point.x)))
        if reduction > 0:
            point = trial
            J = _weighted_jacobian(jac(point.x), point, n_plain)
        if converged:                                   # (a zero step always is: xtol)
            return Solution(point.x, point.cost, J, n_iter + 1)
        new_radius = (0.25 * step_norm if ratio < 0.25 else
                      2.0 * radius if ratio > 0.75 and step_norm > 0.95 * radius else radius)
        alpha *= radius / new_radius
        radius = new_radius
    raise ConvergenceError(f"robust least squares: no convergence in {max_iter} steps (cost {point.cost:.6g}, "
                           f"ftol {ftol}, xtol {xtol}, gtol {gtol})")


def _norm(v) -> float:
    """Euclidean norm sqrt(v . v) of a vector (numpy.linalg.norm's value, without its overhead)."""
    return math.sqrt(v @ v)


def _gauss_newton_step(J, g, radius):
    """The Gauss-Newton step dx = -(J~^T J~)^-1 J~^T f~ when J~^T J~ is positive definite (Cholesky
    succeeds, so J~ has full rank) and ||dx|| <= radius, else None (the cheap path of
    _trust_region_step, without its SVD)."""
    A = J.T @ J
    try:
        np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        return None
    step = np.linalg.solve(A, -g)
    return step if _norm(step) <= radius else None


def _trust_region_step(sv, Vt, suf, m, radius, alpha, rtol=0.01, max_iter=10):
    """(dx, alpha): the minimiser of ||J~ dx + f~|| with ||dx|| <= radius (Moré 1977, as scipy's
    solve_lsq_trust_region), from the SVD J~ = U diag(sv) Vt and suf = sv U^T f~: the
    Gauss-Newton step -Vt^T (suf / sv^2) when J~ has full rank and it fits, else
    dx(alpha) = -Vt^T (suf / (sv^2 + alpha)) with alpha >= 0 found by Newton's method on
    phi(alpha) = ||dx(alpha)|| - radius to |phi| < rtol radius, then scaled onto the boundary."""
    full_rank = m >= Vt.shape[1] and sv[-1] > EPS * m * sv[0]
    if full_rank:
        step = -Vt.T @ (suf / sv**2)
        if _norm(step) <= radius:
            return step, 0.0

    def phi_and_derivative(a):
        denom = sv**2 + a
        norm = np.linalg.norm(suf / denom)
        return norm - radius, -np.sum(suf**2 / denom**3) / norm

    upper = np.linalg.norm(suf) / radius
    lower = -np.divide(*phi_and_derivative(0.0)) if full_rank else 0.0
    if not full_rank and alpha == 0:
        alpha = max(0.001 * upper, (lower * upper) ** 0.5)
    for _ in range(max_iter):
        if alpha < lower or alpha > upper:
            alpha = max(0.001 * upper, (lower * upper) ** 0.5)
        phi, derivative = phi_and_derivative(alpha)
        if phi < 0:
            upper = alpha
        ratio = phi / derivative
        lower = max(lower, alpha - ratio)
        alpha -= (phi + radius) * ratio / radius
        if abs(phi) < rtol * radius:
            break
    step = -Vt.T @ (suf / (sv**2 + alpha))
    return step * (radius / np.linalg.norm(step)), alpha


def _evaluate(fun, x, rho, f_scale, n_plain) -> _Point:
    """x with C(x) and the loss-weighted residuals: with z = (f / s)^2 and rho, rho', rho'' at z,
    the robust residuals cost s^2 rho and f~ = rho' f / sqrt(w), w = max(rho' + 2 rho'' z, EPS)
    (Triggs' correction, scipy's EPS floor)."""
    raw_f = np.asarray(fun(x), dtype=float)
    z = (raw_f[n_plain:] / f_scale) ** 2
    r = rho(z)
    sqrt_w = np.sqrt(np.maximum(r[1] + 2.0 * r[2] * z, EPS))
    plain = raw_f[:n_plain]
    f = raw_f.copy()
    f[n_plain:] *= r[1] / sqrt_w
    return _Point(x, 0.5 * (plain @ plain + f_scale**2 * r[0].sum()), f, sqrt_w)


def _weighted_jacobian(J, point: _Point, n_plain):
    """J~: the robust rows of J (m, n) multiplied by sqrt(w) at the point."""
    J = np.array(J, dtype=float)
    J[n_plain:] *= point.sqrt_w[:, None]
    return J
