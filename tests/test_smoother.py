"""RTS smoother: agreement with filterpy, the batch (information-form) solution with control
inputs, and a lower error than the filter on an EKF range-tracking run."""

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FilterpyKF

from wsnloc.filters.kalman import ExtendedKalmanFilter, KalmanFilter
from wsnloc.filters.measurement_models import RangeModel, Stacked
from wsnloc.filters.motion_models import constant_velocity, pva
from wsnloc.filters.smoother import rts_smooth

ANCHORS = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]])
H_POS = np.hstack([np.eye(2), np.zeros((2, 2))])


def _block_row(blocks, n_states, n):
    """One block row of a whole-trajectory design matrix: [(state index, block), ...]."""
    row = np.zeros((blocks[0][1].shape[0], n_states * n))
    for j, M in blocks:
        row[:, j * n:(j + 1) * n] = M
    return row


def test_kf_smoother_equals_filterpy_with_varying_steps_and_static_epochs():
    rng = np.random.default_rng(3)
    R = np.eye(2) * 0.25
    kf = KalmanFilter(np.zeros(4), np.eye(4) * 4.0, np.eye(4), np.zeros((4, 4)), H_POS, R)
    xs, Ps, Fs, Qs = [], [], [], []
    truth = np.zeros(2)
    for k in range(60):
        if k > 0 and k % 7 != 0:                              # every 7th epoch is static: no predict
            dt = 0.4 + 0.05 * (k % 3)
            kf.F, kf.Q = constant_velocity(dt, 0.5)
            kf.predict()
            truth = truth + dt * np.array([0.6, 0.3])
        else:
            kf.F, kf.Q = np.eye(4), np.zeros((4, 4))
        kf.update(truth + rng.normal(0, 0.5, 2))
        Fs.append(kf.F)
        Qs.append(kf.Q)
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    ours_x, ours_P = rts_smooth(xs, Ps, Fs, Qs)
    ref_x, ref_P, _, _ = FilterpyKF(dim_x=4, dim_z=2).rts_smoother(np.array(xs), np.array(Ps), Fs, Qs)
    np.testing.assert_allclose(ours_x, ref_x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours_P, ref_P, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours_x[-1], xs[-1])                 # the last step is the filtered one
    assert np.all(np.trace(ours_P, axis1=1, axis2=2) <= np.trace(np.array(Ps), axis1=1, axis2=2) + 1e-12)


def test_smoother_with_inputs_equals_the_batch_solution():
    """Linear-Gaussian chain with control inputs: the smoothed means are the minimiser of the
    whole-trajectory least squares and the covariances the diagonal blocks of its inverse
    information matrix."""
    rng = np.random.default_rng(5)
    n, N, dt = 6, 25, 0.5
    F, B, Q = pva(dt, 0.2, 0.05)
    Q = Q + np.eye(n) * 1e-4                                    # positive definite for the batch whitening
    R = np.eye(2) * 0.3
    H = np.hstack([np.eye(2), np.zeros((2, 4))])
    x0, P0 = np.zeros(n), np.eye(n)
    us = rng.normal(0, 0.5, (N, 2))
    us[0] = np.nan
    zs = rng.normal(0, 1.0, (N, 2)) + np.arange(N)[:, None] * 0.3
    kf = KalmanFilter(x0, P0, F, Q, H, R)
    xs, Ps = [], []
    for k in range(N):
        if k > 0:
            kf.predict(u=us[k], B=B)
        kf.update(zs[k])
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    sm_x, sm_P = rts_smooth(xs, Ps, [F] * N, [Q] * N, us=us, Bs=[B] * N)

    Wp, Wq, Wr = (np.linalg.inv(np.linalg.cholesky(c)) for c in (P0, Q, R))     # whitening L^-1
    rows, rhs = [_block_row([(0, Wp)], N, n)], [Wp @ x0]
    for k in range(N):
        rows.append(_block_row([(k, Wr @ H)], N, n))
        rhs.append(Wr @ zs[k])
        if k > 0:
            rows.append(_block_row([(k, Wq), (k - 1, -Wq @ F)], N, n))
            rhs.append(Wq @ B @ us[k])
    A, b = np.vstack(rows), np.concatenate(rhs)
    batch = np.linalg.lstsq(A, b, rcond=None)[0].reshape(N, n)
    cov = np.linalg.inv(A.T @ A)
    np.testing.assert_allclose(sm_x, batch, atol=1e-9)
    for k in range(N):
        np.testing.assert_allclose(sm_P[k], cov[k * n:(k + 1) * n, k * n:(k + 1) * n], atol=1e-9)


def test_smoothing_an_ekf_range_track_lowers_the_error():
    rng = np.random.default_rng(11)
    dt, sigma = 0.5, 0.3
    F, Q = constant_velocity(dt, 0.3)
    t = np.arange(120) * dt
    truth = np.column_stack([5 + 3.5 * np.cos(0.15 * t), 4 + 3.0 * np.sin(0.15 * t)])
    ekf = ExtendedKalmanFilter(np.array([*truth[0], 0.0, 0.0]), np.diag([1.0, 1.0, 0.5, 0.5]), F, Q)
    xs, Ps = [], []
    for k, p in enumerate(truth):
        if k > 0:
            ekf.predict()
        model = Stacked([RangeModel(ANCHORS, np.full(4, sigma))], np.hypot(*(p - ANCHORS).T) + rng.normal(0, sigma, 4))
        ekf.update_nonlinear(model.z, model.h, model.jacobian, model.R())
        xs.append(ekf.x.copy())
        Ps.append(ekf.P.copy())
    sm_x, _ = rts_smooth(xs, Ps, [F] * len(t), [Q] * len(t))
    rmse_filtered = np.sqrt(np.mean(np.sum((np.array(xs)[:, :2] - truth) ** 2, axis=1)))
    rmse_smoothed = np.sqrt(np.mean(np.sum((sm_x[:, :2] - truth) ** 2, axis=1)))
    assert rmse_smoothed < 0.8 * rmse_filtered


def test_mismatched_lengths_are_rejected():
    with pytest.raises(ValueError, match="Qs has 2 steps, xs has 3"):
        rts_smooth(np.zeros((3, 2)), np.tile(np.eye(2), (3, 1, 1)), np.tile(np.eye(2), (3, 1, 1)),
                   np.tile(np.eye(2), (2, 1, 1)))
