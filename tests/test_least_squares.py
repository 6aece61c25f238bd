"""The numpy robust least-squares solver (filters.least_squares) against
scipy.optimize.least_squares (trf, the same losses and tolerances) on random sliding-window
problems with outliers, and its iteration limit."""

import numpy as np
import pytest

from wsnloc.filters.least_squares import LOSSES, ConvergenceError, robust_least_squares
from wsnloc.filters.sliding_window import RangeFactors, SlidingWindowEstimator

optimize = pytest.importorskip("scipy.optimize")

ANCHORS = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0], [5.0, -2.0]])
TOLERANCES = {"ftol": 1e-12, "xtol": 1e-12, "gtol": 1e-12}


def window_problem(rng, with_prior: bool):
    """(estimator, prior or None, ranges, start): a 2 s window of 5 knots, ranges at 4 Hz to
    random anchors from a random constant-velocity walk, 0.1 m noise and 15 % outliers of
    1-8 m; start: the truth perturbed by 0.5 m (m/s)."""
    est = SlidingWindowEstimator(window_s=2.0, knot_s=0.5, accel_sigma=rng.uniform(0.2, 1.0))
    knots = 0.5 * np.arange(5)
    v = rng.normal(0, 0.8, 2)
    truth = np.hstack([rng.uniform(1, 9, 2) + knots[:, None] * v, np.tile(v, (5, 1))])
    t = np.sort(rng.uniform(0, 2.0, rng.integers(6, 40)))
    j = np.minimum((t / 0.5).astype(int), 4)
    anchors = ANCHORS[rng.integers(0, len(ANCHORS), len(t))]
    dz = rng.uniform(-1, 1, len(t))
    pos = truth[j, :2] + (t - knots[j])[:, None] * truth[j, 2:]
    r = np.sqrt(np.sum((pos - anchors) ** 2, axis=1) + dz**2) + rng.normal(0, 0.1, len(t))
    outliers = rng.random(len(t)) < 0.15
    r[outliers] += rng.uniform(1, 8, outliers.sum())
    ranges = RangeFactors(j, t - knots[j], anchors, dz, r, np.full(len(t), 0.1))
    prior = ((truth[0] + rng.normal(0, 0.3, 4), np.diag(1 / rng.uniform(0.5, 2, 4))) if with_prior else None)
    return est, prior, ranges, (truth + rng.normal(0, 0.5, truth.shape)).ravel()


def our_solution(est, prior, ranges, start, loss, n_plain):
    return robust_least_squares(lambda th: est._residuals(th, prior, ranges), lambda th: est._jacobian(th, prior, ranges),
                                start, LOSSES[loss], est.f_scale, n_plain, **TOLERANCES)


def scipy_solution(est, prior, ranges, start, loss, n_plain):
    """scipy.optimize.least_squares on the same problem, as the estimator called it before."""
    def composite(z):
        out = LOSSES["linear"](z)
        out[:, n_plain:] = LOSSES[loss](z[n_plain:])
        return out
    return optimize.least_squares(est._residuals, start, jac=est._jacobian, args=(prior, ranges), loss=composite,
                                  f_scale=est.f_scale, method="trf", **TOLERANCES)


@pytest.mark.parametrize("loss", sorted(LOSSES))
def test_solver_matches_scipy_least_squares_on_random_windows(loss):
    """Solution within 1e-6 (m, m/s), cost within 1e-9 relative, loss-weighted J^T J within
    1e-6 relative, on 40 random windows (half with a prior on the first knot)."""
    rng = np.random.default_rng(sorted(LOSSES).index(loss))
    for case in range(40):
        est, prior, ranges, start = window_problem(rng, with_prior=case % 2 == 0)
        n_plain = 16 + (0 if prior is None else 4)
        ours = our_solution(est, prior, ranges, start, loss, n_plain)
        ref = scipy_solution(est, prior, ranges, start, loss, n_plain)
        np.testing.assert_allclose(ours.x, ref.x, rtol=0, atol=1e-6)
        assert ours.cost == pytest.approx(ref.cost, rel=1e-9)
        np.testing.assert_allclose(ours.jac.T @ ours.jac, ref.jac.T @ ref.jac, rtol=1e-6,
                                   atol=1e-6 * np.abs(ref.jac.T @ ref.jac).max())


def test_a_quadratic_is_solved_in_one_gauss_newton_step():
    A = np.array([[2.0, 1.0], [0.0, 3.0], [1.0, 1.0]])
    b = np.array([1.0, -2.0, 0.5])
    solution = robust_least_squares(lambda x: A @ x - b, lambda x: A, np.zeros(2))
    np.testing.assert_allclose(solution.x, np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-12)
    assert solution.n_iter <= 2                       # the step, then the stop on gtol or ftol


def test_no_convergence_within_the_iteration_limit_raises():
    """Rosenbrock's valley from (-1.2, 1) takes more than 3 steps."""
    def fun(x):
        return np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]])

    def jac(x):
        return np.array([[-20 * x[0], 10.0], [-1.0, 0.0]])
    with pytest.raises(ConvergenceError, match="no convergence in 3 steps"):
        robust_least_squares(fun, jac, [-1.2, 1.0], max_iter=3)
    np.testing.assert_allclose(robust_least_squares(fun, jac, [-1.2, 1.0], max_iter=200).x, [1.0, 1.0], atol=1e-6)
