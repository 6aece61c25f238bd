"""Fast paths of the filters' small matrices: the motion models' F, B, Q against their block
formulas (filters.motion_models docstring), the Kalman update's 1 x 1 inverse against
numpy.linalg.inv, bit for bit, and the information-form update for a diagonal R against the
Joseph-form update."""

import numpy as np
import pytest

from wsnloc.filters.kalman import diagonal_update, inverse, joseph_update, nis
from wsnloc.filters.measurement_models import RangeModel
from wsnloc.filters.motion_models import constant_velocity, pva

I2, Z2 = np.eye(2), np.zeros((2, 2))


@pytest.mark.parametrize("dt", [0.0, 0.1, 0.5, 1.7])
def test_constant_velocity_matches_its_block_formula(dt):
    F, Q = constant_velocity(dt, 0.4, 0.7)
    G = np.vstack([dt**2 / 2.0 * I2, dt * I2])
    np.testing.assert_array_equal(F, np.block([[I2, dt * I2], [Z2, I2]]))
    np.testing.assert_array_equal(Q, G @ np.diag([0.4**2, 0.7**2]) @ G.T)


@pytest.mark.parametrize("dt", [0.0, 0.1, 0.5, 1.7])
def test_pva_matches_its_block_formula(dt):
    F, B, Q = pva(dt, 0.3, 0.02)
    B_block = np.vstack([dt**2 / 2 * I2, dt * I2, Z2])
    np.testing.assert_array_equal(F, np.block([[I2, dt * I2, -dt**2 / 2 * I2], [Z2, I2, -dt * I2], [Z2, Z2, I2]]))
    np.testing.assert_array_equal(B, B_block)
    expected = B_block @ B_block.T * 0.3**2
    expected[4:, 4:] += I2 * 0.02**2 * dt
    np.testing.assert_array_equal(Q, expected)


def test_inverse_of_a_scalar_is_bit_identical_to_numpy():
    rng = np.random.default_rng(0)
    values = np.concatenate([rng.lognormal(0, 8, 5000), -rng.lognormal(0, 8, 500), [1e-300, 3.0, 7.0]])
    for v in values:
        np.testing.assert_array_equal(inverse(np.array([[v]])), np.linalg.inv(np.array([[v]])))


def test_inverse_of_a_matrix_is_numpys():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(3, 3))
    S = A @ A.T + np.eye(3)
    np.testing.assert_array_equal(inverse(S), np.linalg.inv(S))


def _bank(rng, runs, n, m):
    """Random SPD P, H, y and diagonal variances r of a bank; each run's last rows padded
    (H = 0, y = 0, r = 1) as the array EKF pads epochs."""
    A = rng.normal(size=(runs, n, n))
    P = A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(n)
    H = rng.normal(size=(runs, m, n))
    y = rng.normal(size=(runs, m))
    r = rng.lognormal(-2, 1.5, size=(runs, m))
    used = rng.integers(1, m + 1, runs)
    pad = np.arange(m)[None, :] >= used[:, None]
    H[pad], y[pad], r[pad] = 0.0, 0.0, 1.0
    return rng.normal(size=(runs, n)), P, y, H, r


@pytest.mark.parametrize("n, m", [(4, 1), (4, 33), (6, 5), (2, 12)])
def test_diagonal_update_equals_the_joseph_update(n, m):
    x, P, y, H, r = _bank(np.random.default_rng(n * 100 + m), 50, n, m)
    info = diagonal_update(x, P, y, H, r)
    full = joseph_update(x, P, y, H, r[..., None] * np.eye(m))
    assert info.ok.all() and full.ok.all()
    np.testing.assert_allclose(info.x, full.x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(info.P, full.P, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(info.nis, nis(y, full.S_inv), rtol=1e-9, atol=1e-9)
    one = diagonal_update(x[3], P[3], y[3], H[3], r[3])           # one filter: no batch axis
    np.testing.assert_allclose(one.x, full.x[3], rtol=1e-9, atol=1e-9)


def test_diagonal_update_of_a_singular_p_and_a_non_finite_measurement():
    """A singular P (e.g. a known coordinate) needs no P^-1 in the solved form and gives the Joseph
    update; a non-finite measurement keeps the prior (ok False, NIS NaN) as there."""
    x, P, y, H, r = _bank(np.random.default_rng(7), 4, 4, 6)
    P[1] = np.diag([1.0, 1.0, 0.0, 0.0])
    y[2, 0] = np.nan
    info = diagonal_update(x, P, y, H, r)
    full = joseph_update(x, P, y, H, r[..., None] * np.eye(6))
    np.testing.assert_array_equal(info.ok, [True, True, False, True])
    np.testing.assert_array_equal(info.ok, full.ok)
    np.testing.assert_allclose(info.x, full.x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(info.P, full.P, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(info.x[2], x[2])
    assert np.isnan(info.nis[2])


@pytest.mark.parametrize("sigma", [0.3, np.array([0.1, 0.25, 0.4])])
def test_range_noise_is_the_diagonal_of_the_squared_sigmas(sigma):
    model = RangeModel(np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]]), sigma)
    np.testing.assert_array_equal(model.R(), np.diag(np.broadcast_to(sigma, 3) ** 2))


def test_distances_of_many_states_equal_those_of_each_state():
    """h_many row by row equals h (same floating-point operations: bit for bit), also for a
    particle on an anchor (the 1 mm floor)."""
    rng = np.random.default_rng(2)
    anchors = rng.uniform(0, 20, (7, 2))
    X = np.vstack([rng.uniform(0, 20, (200, 4)), [[*anchors[3], 0.0, 0.0]]])
    model = RangeModel(anchors, np.full(7, 0.1))
    np.testing.assert_array_equal(model.h_many(X), np.array([model.h(x) for x in X]))
