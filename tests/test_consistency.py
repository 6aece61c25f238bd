"""NEES / NIS, chi-square bands and verdicts: quantiles against scipy.stats, a matched
linear Kalman filter inside its band, an over-confident one flagged optimistic."""

import numpy as np
import pytest
from scipy.stats import chi2

from wsnloc.filters.kalman import KalmanFilter
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.metrics import consistency


@pytest.mark.parametrize("dof", [1, 2, 3.5, 4, 40, 400, 32000])
@pytest.mark.parametrize("q", [0.025, 0.5, 0.975])
def test_chi2_quantile_matches_scipy_stats(dof, q):
    assert consistency.chi2_quantile(dof, q) == pytest.approx(chi2.ppf(q, dof), rel=1e-10)


def test_band_degrees_of_freedom():
    low, high = consistency.chi2_band(50 * 4, 50)
    assert (low, high) == pytest.approx((chi2.ppf(0.025, 200) / 50, chi2.ppf(0.975, 200) / 50), rel=1e-10)
    # per-step NIS dofs: 2 runs with 3 ranges and 1 run with 2 at the same step -> chi2(8) / 3
    values = np.array([[1.0, np.nan], [2.0, 4.0], [3.0, 5.0]])
    dof = np.array([[3, 3], [3, 2], [2, 2]])
    test = consistency.consistency_test(values, dof)
    np.testing.assert_allclose(test.average, [2.0, 4.5])
    np.testing.assert_allclose(test.low, [chi2.ppf(0.025, 8) / 3, chi2.ppf(0.025, 4) / 2], rtol=1e-10)
    np.testing.assert_allclose(test.high, [chi2.ppf(0.975, 8) / 3, chi2.ppf(0.975, 4) / 2], rtol=1e-10)
    assert test.time_average == pytest.approx(3.0)
    assert test.inflation == 1.0       # runs spread less than chi-square: no correlation inflation
    assert (test.time_low, test.time_high) == pytest.approx((chi2.ppf(0.025, 12) / 5, chi2.ppf(0.975, 12) / 5))


def test_normalized_squared_full_and_position_only():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(7, 4, 4))
    P = A @ np.swapaxes(A, 1, 2) + np.eye(4)
    e = rng.normal(size=(7, 4))
    full = [v @ np.linalg.inv(C) @ v for v, C in zip(e, P)]
    position = [v[:2] @ np.linalg.inv(C[:2, :2]) @ v[:2] for v, C in zip(e, P)]
    np.testing.assert_allclose(consistency.normalized_squared(e, P), full, rtol=1e-10)
    np.testing.assert_allclose(consistency.normalized_squared(e, P, components=(0, 1)), position, rtol=1e-10)


def test_time_correlation_inflation():
    rng = np.random.default_rng(2)
    white = rng.chisquare(4, size=(400, 50))
    held = np.repeat(rng.chisquare(4, size=(400, 1)), 50, axis=1)   # one value held for 50 steps
    assert consistency.time_correlation_inflation(white.sum(axis=1), np.full(400, 200.0)) < 1.1
    assert consistency.time_correlation_inflation(held.sum(axis=1), np.full(400, 200.0)) == pytest.approx(50, rel=0.2)
    test = consistency.consistency_test(held, 4)
    # the band of the time average is the one of 400 independent values
    assert (test.time_low, test.time_high) == pytest.approx(
        (test.inflation * chi2.ppf(0.025, 1600 * 50 / test.inflation) / 20000,
         test.inflation * chi2.ppf(0.975, 1600 * 50 / test.inflation) / 20000), rel=1e-9)
    assert test.time_high - test.time_low > 5 * np.diff(consistency.chi2_band(80000, 20000))[0]


def test_verdicts_on_chi_square_samples_with_varying_dof():
    rng = np.random.default_rng(5)
    dof = rng.integers(1, 5, size=(40, 200))
    values = rng.chisquare(dof).astype(float)
    values[rng.random(values.shape) < 0.1] = np.nan      # steps without an update
    assert consistency.consistency_test(values, dof).verdict == "consistent"
    assert consistency.consistency_test(1.5 * values, dof).verdict == "optimistic"
    assert consistency.consistency_test(0.6 * values, dof).verdict == "pessimistic"


def kalman_nees_and_nis(seed, runs=50, steps=100, r_scale=1.0):
    """NEES (runs, steps) of a PV Kalman filter on data from its own model (filter R = true R
    x r_scale), with its NIS."""
    rng = np.random.default_rng(seed)
    F, Q = constant_velocity(0.2, 0.6)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = np.diag([0.3, 0.2]) ** 2
    P0 = np.diag([1.0, 1.0, 0.25, 0.25])
    nees, nis = np.empty((runs, steps)), np.empty((runs, steps))
    for r in range(runs):
        x = rng.multivariate_normal(np.zeros(4), P0)
        kf = KalmanFilter(np.zeros(4), P0, F, Q, H, R * r_scale)
        for k in range(steps):
            if k:
                x = F @ x + rng.multivariate_normal(np.zeros(4), Q, method="eigh")
                kf.predict()
            kf.update(H @ x + rng.multivariate_normal(np.zeros(2), R))
            nees[r, k] = consistency.normalized_squared(x - kf.x, kf.P)
            nis[r, k] = kf.nis
    return nees, nis


def test_matched_kalman_filter_is_consistent_and_overconfident_one_optimistic():
    verdicts, shares = [], []
    for seed in range(5):
        nees, nis = kalman_nees_and_nis(seed)
        anees, anis = consistency.consistency_test(nees, 4), consistency.consistency_test(nis, 2)
        verdicts += [anees.verdict, anis.verdict]
        shares += [anees.share_inside, anis.share_inside]
    assert verdicts.count("consistent") >= 8, verdicts    # 95 % tests: ~1 in 20 rejects a consistent filter
    assert min(shares) >= 0.85, shares      # 95 % bands: ~95 of 100 steps inside
    nees, nis = kalman_nees_and_nis(7, r_scale=0.1)
    assert consistency.consistency_test(nees, 4).verdict == "optimistic"
    assert consistency.consistency_test(nis, 2).verdict == "optimistic"
