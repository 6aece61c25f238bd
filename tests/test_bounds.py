"""Static CRLB / GDOP against closed forms and numerical Jacobians; PCRB against the Kalman
filter (linear-Gaussian), the static CRLB (Q = 0) and a matched-model EKF Monte Carlo."""

import numpy as np
import pytest

from wsnloc.filters.kalman import ExtendedKalmanFilter, KalmanFilter
from wsnloc.filters.measurement_models import RangeModel, RssModel
from wsnloc.filters.motion_models import constant_velocity, position_only
from wsnloc.metrics import bounds

SQUARE = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])


def numerical_jacobian(f, x, eps=1e-6):
    x = np.asarray(x, dtype=float)
    return np.column_stack([(f(x + eps * e) - f(x - eps * e)) / (2 * eps) for e in np.eye(len(x))])


def as_matrix(entries):
    return bounds.to_matrices(entries, 2)


def test_crlb_closed_forms():
    centre = np.array([[5.0, 5.0]])
    # four anchors at 45 deg around the point: G^T G = 2 I, trace((G^T G)^-1) = 1
    assert bounds.gdop(centre, SQUARE) == pytest.approx([1.0], abs=1e-12)
    assert bounds.toa_crlb(centre, SQUARE, 0.3) == pytest.approx([0.3], abs=1e-12)
    # three anchors 120 deg apart: G^T G = 3/2 I, bound = sigma sqrt(4/3)
    angles = np.deg2rad([90.0, 210.0, 330.0])
    tri = 4.0 * np.column_stack([np.cos(angles), np.sin(angles)])
    assert bounds.toa_crlb(np.zeros((1, 2)), tri, 0.1) == pytest.approx([0.1 * np.sqrt(4 / 3)], rel=1e-12)
    # RSS: |g_i| = 10 n / (ln10 d); four anchors at d = 5 sqrt 2: J = 2 |g|^2 / sigma^2 I
    g = 10 * 3.0 / (np.log(10) * 5 * np.sqrt(2))
    expected = np.sqrt(2 * 4.0**2 / (2 * g**2))
    assert bounds.rss_crlb(centre, SQUARE, 3.0, 4.0) == pytest.approx([expected], rel=1e-12)
    # hybrid: informations add
    both = 1 / (1 / 0.3**2 + 1 / expected**2)
    assert bounds.hybrid_crlb(centre, SQUARE, 0.3, SQUARE, 3.0, 4.0) == pytest.approx([np.sqrt(both)], rel=1e-12)
    # two anchors in line with the point: singular, infinite bound
    assert np.isinf(bounds.toa_crlb(np.array([[5.0, 0.0]]), SQUARE[:2], 0.1))[0]


def test_information_terms_match_numerical_jacobians():
    rng = np.random.default_rng(3)
    points = rng.uniform(-2, 12, size=(25, 2))
    sigma = np.array([0.1, 0.2, 0.15, 0.3])
    dz = np.array([1.2, -0.4, 2.0, 0.0])
    toa = bounds.toa_information_terms(points, SQUARE, sigma, dz)
    rss = bounds.rss_information_terms(points, SQUARE, 2.7, 5.0)
    range_model = RangeModel(SQUARE, sigma, dz)
    rss_model = RssModel(SQUARE, -45.0 - 81.0, 2.7, 5.0, d0_m=1e-3)   # the same law, its near-field floor at 1 mm
    for p, t_toa, t_rss in zip(points, toa, rss):
        for model, terms in ((range_model, t_toa), (rss_model, t_rss)):
            H = numerical_jacobian(model.h, p)
            expected = H.T @ np.linalg.inv(model.R()) @ H
            np.testing.assert_allclose(as_matrix(terms.sum(axis=0)), expected, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(as_matrix(toa.sum(axis=1)), bounds.model_information(range_model, points),
                               rtol=1e-12)
    # the bound is the trace of the inverse FIM
    fim = as_matrix(toa.sum(axis=1))
    np.testing.assert_allclose(bounds.toa_crlb(points, SQUARE, sigma, dz),
                               np.sqrt(np.trace(np.linalg.inv(fim), axis1=1, axis2=2)), rtol=1e-10)


def test_gdop_scales_the_toa_bound():
    _, _, points = bounds.grid_points(10.0, 10.0, 0.7)
    np.testing.assert_allclose(bounds.toa_crlb(points, SQUARE, 0.25), 0.25 * bounds.gdop(points, SQUARE), rtol=1e-12)


def test_available_information_sums_the_heard_anchors():
    rng = np.random.default_rng(4)
    points = rng.uniform(0, 10, size=(30, 2))
    terms = bounds.toa_information_terms(points, SQUARE, 0.2)
    available = rng.random((3, 30, 4)) < 0.5              # 3 runs, 30 steps, 4 anchors
    expected = [[terms[k, available[r, k]].sum(axis=0) for k in range(30)] for r in range(3)]
    np.testing.assert_allclose(bounds.available_information(terms, available), expected, rtol=1e-12)


def test_pcrb_equals_kalman_covariance_for_linear_gaussian_model():
    F, Q = constant_velocity(0.2, 0.7, 0.4)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = np.array([[0.09, 0.02], [0.02, 0.04]])
    P0 = np.diag([4.0, 4.0, 1.0, 1.0])
    available = np.random.default_rng(1).random(60) < 0.6
    kf = KalmanFilter(np.zeros(4), P0, F, Q, H, R)
    expected = []
    for k, update in enumerate(available):
        if k:
            kf.predict()
        if update:
            kf.update(np.zeros(2))
        expected.append(kf.P.copy())
    information = np.where(available[:, None, None], H.T @ np.linalg.inv(R) @ H, 0.0)
    np.testing.assert_allclose(bounds.pcrb(P0, F, Q, information), np.array(expected), rtol=0, atol=1e-9)


def test_static_pcrb_equals_closed_form_crlb():
    """P model with Q = 0: K range scans of a fixed point give the CRLB of one scan / sqrt(K)."""
    F, Q = position_only(0.0)
    point = np.array([[3.0, 7.0]])
    K = 50
    information = np.repeat(as_matrix(bounds.toa_information_terms(point, SQUARE, 0.2).sum(axis=1)), K, axis=0)
    P = bounds.pcrb(np.eye(2) * 1e12, F, Q, information)
    expected = bounds.toa_crlb(point, SQUARE, 0.2)[0] / np.sqrt(np.arange(1, K + 1))
    np.testing.assert_allclose(bounds.position_rmse_bound(P), expected, rtol=1e-9)


def simulate_pv_ranges(rng, runs, steps, F, Q, P0, anchors, sigma):
    """True PV trajectories (runs, steps, 4) from x_0 ~ N(m0, P0) and ranges with N(0, sigma^2)."""
    m0 = np.array([5.0, 5.0, 0.5, 0.2])
    x = m0 + rng.multivariate_normal(np.zeros(4), P0, size=runs)
    noise = rng.multivariate_normal(np.zeros(4), Q, size=(runs, steps), method="eigh")
    states = np.empty((runs, steps, 4))
    for k in range(steps):
        if k:
            x = x @ F.T + noise[:, k]
        states[:, k] = x
    diff = states[:, :, None, :2] - anchors[None, None]
    ranges = np.linalg.norm(diff, axis=-1) + sigma * rng.standard_normal((runs, steps, len(anchors)))
    return m0, states, ranges


def test_matched_ekf_rmse_is_at_or_above_and_close_to_sqrt_pcrb():
    """Each run hears each anchor at each step with probability 0.8 (its own availability),
    all of them at the first step (from the 0.5 m prior an EKF update on one or two ranges
    is far from linear); the bound is the mean of the per-run PCRBs."""
    rng = np.random.default_rng(11)
    runs, steps, sigma = 300, 80, 0.05
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [5.0, 12.0]])
    F, Q = constant_velocity(0.2, 0.5)
    P0 = np.diag([0.25, 0.25, 0.04, 0.04])
    m0, states, ranges = simulate_pv_ranges(rng, runs, steps, F, Q, P0, anchors, sigma)
    available = rng.random(ranges.shape) < 0.8
    available[:, 0] = True
    sq_err = np.empty((runs, steps))
    for r in range(runs):
        ekf = ExtendedKalmanFilter(m0, P0, F, Q)
        for k in range(steps):
            if k:
                ekf.predict()
            heard = available[r, k]
            model = RangeModel(anchors[heard], np.full(heard.sum(), sigma))
            ekf.update_nonlinear(ranges[r, k, heard], model.h, model.jacobian, model.R())
            sq_err[r, k] = np.sum((ekf.x[:2] - states[r, k, :2]) ** 2)
    terms = bounds.toa_information_terms(states.reshape(-1, 4), anchors, sigma).reshape(runs, steps, -1, 3)
    information = bounds.available_information(terms, available)
    mean_bound = bounds.pcrb(P0, F, Q, bounds.to_matrices(information, 4)).mean(axis=0)
    bound_mse = bounds.position_rmse_bound(mean_bound) ** 2
    # RMSE over 300 runs: relative standard error ~ 1/sqrt(600) ~ 4 % per step, 80 steps
    ratio = np.sqrt(sq_err.mean(axis=0) / bound_mse)
    assert np.all(ratio > 0.85) and np.all(ratio < 1.2), ratio
    overall = np.sqrt(sq_err.mean() / bound_mse.mean())    # RMSE / sqrt(PCRB) over all steps
    assert 0.97 <= overall <= 1.2, overall


def test_bound_figures_render_deterministically(campaign):
    from wsnloc.metrics.consistency import consistency_test
    from wsnloc.report import bound_figures

    subset = campaign.anchors[campaign.anchors["anchor_id"].isin(campaign.spec["subsets"]["UWB=9"])]
    x, y, points = bounds.grid_points(30.0, 15.0, 1.0)
    xy = subset[["x", "y"]].to_numpy()
    panels = {"TOA CRLB [m]": bounds.toa_crlb(points, xy, 0.1).reshape(len(y), len(x)),
              "GDOP": bounds.gdop(points, xy).reshape(len(y), len(x))}
    t = np.arange(20) * 0.2
    test = consistency_test(np.random.default_rng(0).chisquare(4, size=(10, 20)), 4)
    for render in (lambda: bound_figures.bound_maps(campaign, subset, x, y, panels),
                   lambda: bound_figures.pcrb_vs_rmse(t, {"EKF": 0.2 + t / 50}, 0.1 + t / 100, "PV model", "test"),
                   lambda: bound_figures.consistency_over_time(t, test, "ANEES", "test")):
        first = render()
        assert first.startswith(b"\x89PNG") and render() == first
