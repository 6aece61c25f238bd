"""Sliding-window batch estimator: Jacobian and losses against numerical differentiation,
exact recovery on noise-free ranges, covariance consistency, robustness to a wild range."""

import numpy as np
import pytest

from wsnloc.filters.sliding_window import (LOSSES, RangeFactors, SlidingWindowEstimator,
                                           white_noise_acceleration_cov)

ANCHORS = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]])
DZ = np.array([1.2, -0.4, 0.8, 0.0])
RATE_HZ = 4.0


def numerical_jacobian(f, x, eps=1e-6):
    return np.column_stack([(f(x + e) - f(x - e)) / (2 * eps) for e in np.eye(len(x)) * eps])


def truth_at(t):
    """Constant-velocity truth: (len(t), 4) [x, y, vx, vy]."""
    t = np.atleast_1d(t)
    v = np.array([0.8, 0.3])
    return np.hstack([np.array([2.0, 1.5]) + t[:, None] * v, np.tile(v, (len(t), 1))])


def measurements(t_end, window_s, noise=None, wild=None):
    """All four ranges at every RATE_HZ epoch in [t_end - window_s, t_end]; noise: Generator
    for 0.1 m Gaussian noise; wild: (index, error in m) added to one range."""
    epochs = np.arange(np.ceil((t_end - window_s) * RATE_HZ - 1e-9), np.floor(t_end * RATE_HZ + 1e-9) + 1) / RATE_HZ
    t = np.repeat(epochs, len(ANCHORS))
    anchors = np.tile(ANCHORS, (len(epochs), 1))
    dz = np.tile(DZ, len(epochs))
    pos = truth_at(t)[:, :2]
    r = np.sqrt(np.sum((pos - anchors) ** 2, axis=1) + dz**2)
    if noise is not None:
        r = r + noise.normal(0, 0.1, len(r))
    if wild is not None:
        r[wild[0]] += wild[1]
    return t, anchors, dz, r, np.full(len(r), 0.1)


def test_jacobian_matches_numerical_differentiation():
    est = SlidingWindowEstimator(window_s=1.5, knot_s=0.5)
    t, anchors, dz, r, sigma = measurements(3.0, 1.5)
    knots = 3.0 - 0.5 * np.arange(3, -1, -1)
    j = np.clip(np.floor((t - knots[0]) / 0.5 + 1e-9).astype(int), 0, 3)
    ranges = RangeFactors(j, t - knots[j], anchors, dz, r, sigma)
    rng = np.random.default_rng(0)
    prior = (rng.normal(size=4), np.linalg.inv(np.linalg.cholesky(np.diag([1.0, 2.0, 0.5, 0.3]))))
    theta = truth_at(knots).ravel() + rng.normal(0, 0.5, 16)
    for p in (prior, None):
        np.testing.assert_allclose(est._jacobian(theta, p, ranges),
                                   numerical_jacobian(lambda th: est._residuals(th, p, ranges), theta), atol=1e-7)


@pytest.mark.parametrize("name", sorted(LOSSES))
def test_loss_derivatives_match_numerical_differentiation(name):
    z = np.array([0.01, 0.5, 0.99, 1.01, 3.0, 40.0])
    rho = LOSSES[name](z)
    eps = 1e-6
    np.testing.assert_allclose(rho[1], (LOSSES[name](z + eps)[0] - LOSSES[name](z - eps)[0]) / (2 * eps), rtol=1e-6)
    np.testing.assert_allclose(rho[2], (LOSSES[name](z + eps)[1] - LOSSES[name](z - eps)[1]) / (2 * eps),
                               rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(LOSSES[name](np.array([0.0]))[:2, 0], [0.0, 1.0])   # quadratic near 0


def test_robust_losses_grow_slower_than_quadratic():
    z = np.array([100.0])
    assert LOSSES["huber"](z)[0, 0] == pytest.approx(19.0)              # 2 sqrt(z) - 1
    assert LOSSES["soft_l1"](z)[0, 0] == pytest.approx(2 * (np.sqrt(101.0) - 1))
    assert LOSSES["cauchy"](z)[0, 0] == pytest.approx(np.log(101.0))


def test_continuous_white_noise_acceleration_covariance_is_the_integral():
    """Qc = int_0^dt Phi(s) G q G^T Phi(s)^T ds with G = [0; I], checked by quadrature."""
    dt, sigma = 0.7, 0.4
    s = np.linspace(0, dt, 20001)
    blocks = np.array([[[u**2, u], [u, 1.0]] for u in s]) * sigma**2        # [u; 1] [u; 1]^T q
    numeric = np.kron(np.trapezoid(blocks, s, axis=0), np.eye(2))
    np.testing.assert_allclose(white_noise_acceleration_cov(dt, sigma), numeric, rtol=1e-7)
    assert np.all(np.linalg.eigvalsh(numeric) > 0)


@pytest.mark.parametrize("loss, step_s", [("huber", 0.5), ("linear", 0.5), ("cauchy", 0.5), ("huber", 0.35)])
def test_noise_free_ranges_recover_the_truth(loss, step_s):
    """Consecutive windows (the later ones warm-started and with the previous solution's
    prior, also when the new knots fall between the old ones) recover the truth exactly."""
    est = SlidingWindowEstimator(window_s=2.0, knot_s=0.5, loss=loss)
    for t_end in np.arange(2.0, 6.01, step_s):
        data = measurements(t_end, 2.0)
        result = est.estimate(t_end, *data)
        np.testing.assert_allclose(result.x, truth_at(t_end)[0], atol=1e-6)
        assert result.n_ranges == len(data[0])


def _trajectory_from_the_prior(rng, window_s=2.0, knot_s=0.5):
    """Knot states drawn from the constant-velocity prior (s_j+1 = Phi s_j + w, w ~ N(0, Qc))
    and noisy ranges (0.1 m) at RATE_HZ from the positions p_j + delta v_j the estimator models."""
    n_knots = int(window_s / knot_s) + 1
    Phi = np.array([[1, 0, knot_s, 0], [0, 1, 0, knot_s], [0, 0, 1, 0], [0, 0, 0, 1]])
    L = np.linalg.cholesky(white_noise_acceleration_cov(knot_s, 0.5))
    states = [np.array([3.0, 2.0, 0.6, 0.2])]
    for _ in range(n_knots - 1):
        states.append(Phi @ states[-1] + L @ rng.standard_normal(4))
    states = np.array(states)
    t = np.repeat(np.arange(0, window_s * RATE_HZ + 1) / RATE_HZ, len(ANCHORS))
    j = np.minimum((t / knot_s + 1e-9).astype(int), n_knots - 1)
    anchors, dz = np.tile(ANCHORS, (len(t) // 4, 1)), np.tile(DZ, len(t) // 4)
    pos = states[j, :2] + (t - j * knot_s)[:, None] * states[j, 2:]
    r = np.sqrt(np.sum((pos - anchors) ** 2, axis=1) + dz**2) + rng.normal(0, 0.1, len(t))
    return states[-1], (t, anchors, dz, r, np.full(len(t), 0.1))


def test_prior_from_the_previous_window_carries_a_window_without_ranges():
    est = SlidingWindowEstimator(window_s=2.0, knot_s=0.5)
    before = est.estimate(2.0, *measurements(2.0, 2.0))
    empty = np.zeros(0)
    after = est.estimate(3.0, empty, np.zeros((0, 2)), empty, empty, empty)
    np.testing.assert_allclose(after.x, truth_at(3.0)[0], atol=1e-6)      # constant-velocity extrapolation
    assert after.n_ranges == 0
    assert np.all(np.diag(after.P) > np.diag(before.P))                   # and the uncertainty grows


def test_covariance_is_consistent_with_the_error():
    """On trajectories drawn from the estimator's own model, the normalised estimation error
    squared e^T P^-1 e of the window's end state averages its dimension, 4."""
    nees = []
    for seed in range(200):
        end_state, data = _trajectory_from_the_prior(np.random.default_rng(seed))
        result = SlidingWindowEstimator(window_s=2.0, knot_s=0.5, accel_sigma=0.5, loss="linear").estimate(
            2.0, *data, initial_state=[3.0, 3.0, 0.0, 0.0])
        e = result.x - end_state
        nees.append(e @ np.linalg.solve(result.P, e))
    assert 4 * 0.85 < np.mean(nees) < 4 * 1.15


def _error_with_a_wild_range(loss):
    est = SlidingWindowEstimator(window_s=2.0, knot_s=0.5, loss=loss)
    noise = np.random.default_rng(9)
    for t_end in np.arange(2.0, 4.01, 0.5):
        data = measurements(t_end, 2.0, noise=noise)
        if t_end == 4.0:
            data = measurements(t_end, 2.0, noise=noise, wild=(len(data[0]) - 2, 5.0))   # last epoch, anchor 2
        result = est.estimate(t_end, *data)
    return np.hypot(*(result.x[:2] - truth_at(4.0)[0, :2]))


def test_huber_loss_resists_a_wild_range_that_drags_least_squares():
    """One range 5 m (50 sigma) long at the window's end: least squares moves the estimate
    by metres, the robust losses by decimetres at most."""
    dragged = _error_with_a_wild_range("linear")
    assert dragged > 1.0
    for loss in ("huber", "cauchy", "soft_l1"):
        assert _error_with_a_wild_range(loss) < min(0.25, 0.1 * dragged)


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="loss"):
        SlidingWindowEstimator(loss="tukey")
    with pytest.raises(ValueError, match="knot_s"):
        SlidingWindowEstimator(window_s=1.0, knot_s=2.0)
    est = SlidingWindowEstimator(window_s=2.0)
    t, a, dz, r, s = measurements(3.0, 3.0)
    with pytest.raises(ValueError, match="must lie in"):
        est.estimate(3.0, t, a, dz, r, s)
    with pytest.raises(ValueError, match="at least 4 ranges"):
        est.estimate(3.0, t[-3:], a[-3:], dz[-3:], r[-3:], s[-3:])
    est.estimate(3.0, *measurements(3.0, 2.0))
    with pytest.raises(ValueError, match="increase"):
        est.estimate(0.5, *measurements(0.5, 0.5))


class ScipyWindowEstimator(SlidingWindowEstimator):
    """The estimator as it was before filters.least_squares: each window minimised by
    scipy.optimize.least_squares (trf, the same composite loss and tolerances)."""

    def _solve(self, start, prior, ranges, n_gaussian):
        optimize = pytest.importorskip("scipy.optimize")

        def loss(z):
            out = LOSSES["linear"](z)
            out[:, n_gaussian:] = self.rho(z[n_gaussian:])
            return out
        solution = optimize.least_squares(self._residuals, start, jac=self._jacobian, args=(prior, ranges),
                                          loss=loss, f_scale=self.f_scale, method="trf",
                                          ftol=1e-12, xtol=1e-12, gtol=1e-12)
        return solution.x, solution.jac


@pytest.mark.parametrize("loss", sorted(LOSSES))
def test_estimates_equal_the_scipy_solver(loss):
    """A 12 s run (windows every 0.25 s, 0.1 m noise, a wild range of 2-6 m in one window of
    three): the estimates equal those of the scipy-based estimator to 1e-6 m (m/s), the
    covariances to 1e-6 relative."""
    ours, ref = (cls(window_s=2.0, knot_s=0.5, loss=loss) for cls in (SlidingWindowEstimator, ScipyWindowEstimator))
    rng = np.random.default_rng(5)
    for k, t_end in enumerate(np.arange(2.0, 14.01, 0.25)):
        data = measurements(t_end, 2.0, noise=rng)
        if k % 3 == 0:
            data = measurements(t_end, 2.0, noise=rng, wild=(rng.integers(len(data[0])), rng.uniform(2, 6)))
        a, b = ours.estimate(t_end, *data), ref.estimate(t_end, *data)
        np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-6)
        np.testing.assert_allclose(a.P, b.P, rtol=1e-6, atol=1e-6 * np.abs(b.P).max())


def test_the_window_on_range_differences_far_from_a_small_cluster_stays_within_range_of_the_anchors():
    """Range differences from four anchors 2.6 m x 1.7 m apart, the target 8-23 m away (as on the
    real outdoor UWB cases): along the hyperbolae' asymptotes nothing holds the window, which ran off
    to hundreds of metres. A solution further than max_range_m from every anchor is dropped (counted
    in `skipped`) and the window restarts from a fix."""
    from synthetic import tables_for, tdoa_table
    from wsnloc.estimators import registry
    from wsnloc.estimators.run_data import RunData

    cluster = {"C1": (0.0, 0.0), "C2": (2.6, 0.0), "C3": (2.6, 1.7), "C4": (0.0, 1.7)}

    def far(t):
        t = np.asarray(t, dtype=float)
        return np.column_stack([15.0 + 8.0 * np.cos(t / 20.0), 12.0 + 8.0 * np.sin(t / 20.0)])

    rng = np.random.default_rng(0)
    times = np.arange(0.1, 120.0, 0.1)
    tables = tables_for(times, np.repeat(np.array(["C1"], dtype=object), len(times)), far, cluster)
    tables["ranges"] = tables["ranges"].iloc[:0]
    tables["tdoa"] = tdoa_table(times, far, cluster, noise_m=0.1, rng=rng)
    p = {"measurements": "tdoa", "range_sigma_m": 0.1, "max_range_m": 50.0}
    estimates = registry.run("sliding_window", RunData(tables, None, None, "far"), p)
    anchors = np.array(list(cluster.values()))
    nearest = np.hypot(*(estimates[["x", "y"]].to_numpy()[:, None, :] - anchors[None]).transpose(2, 0, 1)).min(axis=1)
    assert len(estimates) > 100 and nearest.max() <= 50.0 and estimates.attrs["skipped"] > 0
