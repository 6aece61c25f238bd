"""UKF: agreement with filterpy's UnscentedKalmanFilter, exact linear predict, sigma points."""

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints
from filterpy.kalman import UnscentedKalmanFilter as FilterpyUKF

from wsnloc.filters.kalman import KalmanFilter
from wsnloc.filters.measurement_models import RangeModel, RssModel, Stacked
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.filters.ukf import UnscentedKalmanFilter

ANCHORS = np.array([[0.0, 0.0], [8.0, 1.0], [3.0, 7.0], [9.0, 9.0]])


@pytest.mark.parametrize("alpha, beta, kappa", [(1.0, 2.0, 0.0), (0.3, 2.0, 1.0), (0.1, 2.0, 0.0)])
def test_ukf_equals_filterpy_on_identical_inputs(alpha, beta, kappa):
    rng = np.random.default_rng(17)
    x0, P0 = np.array([1.0, 1.0, 0.0, 0.0]), np.diag([1.0, 1.0, 0.1, 0.1])
    ours = UnscentedKalmanFilter(x0, P0, alpha=alpha, beta=beta, kappa=kappa)
    points = MerweScaledSigmaPoints(4, alpha=alpha, beta=beta, kappa=kappa)
    ref = FilterpyUKF(dim_x=4, dim_z=4, dt=0.5, hx=None, fx=lambda x, dt, F: F @ x, points=points)
    ref.x, ref.P = x0.copy(), P0.copy()
    updates = 0
    for k in range(50):
        dt = 0.3 + 0.1 * (k % 4)                                    # the step varies
        F, Q = constant_velocity(dt, 0.3)
        truth = np.array([1.0 + 0.2 * k, 1.0 + 0.1 * k])
        n = k % 5                                                   # 0..4 ranges; 0 = no update
        ours.predict(F, Q)
        ref.Q = Q
        ref.predict(dt=dt, F=F)
        np.testing.assert_allclose(ours.x, ref.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours.P, ref.P, rtol=0, atol=1e-9)
        if n == 0:
            continue
        model = Stacked([RangeModel(ANCHORS[:n], np.full(n, 0.3))],
                        np.hypot(*(truth - ANCHORS[:n]).T) + rng.normal(0, 0.3, n))
        ours.update_model(model)
        ref.update(model.z, R=model.R(), hx=model.h)
        updates += 1
        np.testing.assert_allclose(ours.x, ref.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours.P, ref.P, rtol=0, atol=1e-9)
        assert ours.nis == pytest.approx(float(ref.y @ ref.SI @ ref.y), abs=1e-9)
    assert updates == 40
    assert np.hypot(*(ours.x[:2] - truth)) < 1.0                    # it also tracks


def test_hybrid_range_rss_update_equals_filterpy():
    x0, P0 = np.array([4.0, 3.0, 0.1, 0.0]), np.diag([2.0, 2.0, 0.2, 0.2])
    model = Stacked([RangeModel(ANCHORS[:2], np.full(2, 0.3), dz_m=np.array([1.0, -0.5])),
                     RssModel(ANCHORS[2:], -45.0, 2.8, 4.0)], np.array([5.0, 4.5, -70.0, -72.0]))
    ours = UnscentedKalmanFilter(x0, P0, alpha=0.5)
    ref = FilterpyUKF(dim_x=4, dim_z=4, dt=1.0, hx=model.h, fx=lambda x, dt: x,
                      points=MerweScaledSigmaPoints(4, alpha=0.5, beta=2.0, kappa=0.0))
    ref.x, ref.P, ref.Q = x0.copy(), P0.copy(), np.zeros((4, 4))
    ref.predict()
    ours.update_model(model)
    ref.update(model.z, R=model.R())
    np.testing.assert_allclose(ours.x, ref.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.P, ref.P, rtol=0, atol=1e-9)


def test_sigma_points_reproduce_mean_and_covariance():
    P = np.array([[2.0, 0.3, 0.1, 0.0], [0.3, 1.0, 0.0, 0.2], [0.1, 0.0, 0.5, 0.05], [0.0, 0.2, 0.05, 0.4]])
    ukf = UnscentedKalmanFilter(np.array([1.0, -2.0, 0.5, 0.1]), P, alpha=0.7, kappa=1.0)
    chi = ukf.sigma_points()
    assert chi.shape == (9, 4)
    np.testing.assert_allclose(ukf.Wm @ chi, ukf.x, atol=1e-12)
    d = chi - ukf.x
    np.testing.assert_allclose((ukf.Wc[:, None] * d).T @ d - (ukf.Wc[0] - ukf.Wm[0]) * np.outer(d[0], d[0]), P,
                               atol=1e-12)
    assert ukf.Wm.sum() == pytest.approx(1.0)


def test_linear_measurement_update_equals_the_kalman_filter():
    """With a linear h the unscented transform is exact: the UKF is the KF."""
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.5, 1.0, 0.0, 0.0]])
    R = np.diag([0.2, 0.3])

    class Linear:
        z = np.array([1.2, 0.4])

        def h_many(self, X):
            return X @ H.T

        def R(self):
            return R

    F, Q = constant_velocity(0.5, 0.4)
    x0, P0 = np.array([1.0, 0.0, 0.3, -0.2]), np.eye(4)
    ukf = UnscentedKalmanFilter(x0, P0, alpha=0.2)
    kf = KalmanFilter(x0, P0, F, Q, H, R)
    for _ in range(5):
        ukf.predict(F, Q)
        kf.predict()
        ukf.update_model(Linear())
        kf.update(Linear.z)
    np.testing.assert_allclose(ukf.x, kf.x, atol=1e-10)
    np.testing.assert_allclose(ukf.P, kf.P, atol=1e-10)
    assert ukf.nis == pytest.approx(kf.nis, abs=1e-9)


def test_invalid_scaling_is_rejected():
    with pytest.raises(ValueError, match="alpha"):
        UnscentedKalmanFilter(np.zeros(4), np.eye(4), alpha=0.0)
    with pytest.raises(ValueError, match="kappa"):
        UnscentedKalmanFilter(np.zeros(4), np.eye(4), kappa=-4.0)


def test_covariance_stays_symmetric_with_clustered_anchors_and_a_far_target():
    """Anchors within 2 m of each other and the target ~10 m away (as on the real outdoor UWB runs)
    make P ill-conditioned; without symmetrising Omega and P, the rounding asymmetry between the
    Cholesky factor (one triangle) and H = Pxz^T P^-1 (both) grew ~2x per update until P was
    indefinite and the track left for 1e7 m. Epoch updates of 4 ranges, sigma 0.15 m, accel 1.5 m/s^2."""
    anchors = np.array([[2.58, 0.87], [2.58, -0.87], [2.58, -0.87], [0.69, 0.87]])
    dz = np.array([1.0, 1.0, -0.5, -0.5])               # anchors at two heights
    rng = np.random.default_rng(3)
    F, Q = constant_velocity(0.5, 1.5)
    ukf = UnscentedKalmanFilter(np.array([9.0, -3.0, 0.0, 0.0]), np.diag([1.0, 1.0, 0.25, 0.25]))
    worst = 0.0
    for k in range(400):
        truth = np.array([9.0 + np.sin(0.02 * k), -3.0 - 2.0 * np.sin(0.013 * k)])
        ukf.predict(F, Q)
        ranges = np.sqrt(np.sum((truth - anchors) ** 2, axis=1) + dz**2) + rng.normal(0.0, 0.15, 4)
        ukf.update_model(Stacked([RangeModel(anchors, np.full(4, 0.15), dz_m=dz)], ranges))
        worst = max(worst, np.abs(ukf.P - ukf.P.T).max() / np.abs(ukf.P).max())
        assert np.linalg.eigvalsh(ukf.P).min() > 0, f"P indefinite at update {k}"
    assert worst < 1e-12
    assert np.hypot(*(ukf.x[:2] - truth)) < 3.0
