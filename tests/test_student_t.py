"""The Student-t quantile of the confidence intervals against scipy, its closed forms and symmetry,
and the intervals' computation without scipy."""

import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.special import stdtrit

from wsnloc.metrics.stats import student_t_quantile

LEVELS = (0.975, 0.95, 0.995, 0.9, 0.6)


@pytest.mark.parametrize("q", LEVELS)
def test_quantile_equals_scipy_for_integer_dof_to_1e_12(q):
    dof = np.arange(1, 10001)
    ours = np.array([student_t_quantile(q, int(k)) for k in dof])
    np.testing.assert_allclose(ours, stdtrit(dof, q), rtol=1e-12, atol=0)


@pytest.mark.parametrize("q", (0.975, 0.995, 0.6))
def test_quantile_equals_scipy_for_non_integer_dof(q):
    rng = np.random.default_rng(3)
    dof = np.concatenate([rng.uniform(1.0, 3.0, 300), 10.0 ** rng.uniform(0.0, 5.0, 300)])
    ours = np.array([student_t_quantile(q, k) for k in dof])
    np.testing.assert_allclose(ours, stdtrit(dof, q), rtol=1e-12, atol=0)


@pytest.mark.parametrize("q", LEVELS)
def test_closed_forms_of_one_and_two_degrees_of_freedom(q):
    assert student_t_quantile(q, 1) == pytest.approx(math.tan(math.pi * (q - 0.5)), rel=1e-13)
    u = 2.0 * q - 1.0
    assert student_t_quantile(q, 2) == pytest.approx(u * math.sqrt(2.0 / (1.0 - u * u)), rel=1e-13)


@pytest.mark.parametrize("dof", (1, 2, 3, 19, 1.5, 250.7))
def test_quantile_is_odd_about_one_half(dof):
    assert student_t_quantile(0.5, dof) == 0.0
    for q in (0.975, 0.75, 0.6):
        assert student_t_quantile(1.0 - q, dof) == -student_t_quantile(q, dof)


@pytest.mark.parametrize("q, dof", [(0.0, 5), (1.0, 5), (0.975, 0.5), (0.975, math.inf), (0.975, math.nan)])
def test_quantile_rejects_arguments_outside_its_domain(q, dof):
    with pytest.raises(ValueError):
        student_t_quantile(q, dof)


def test_intervals_load_no_scipy():
    probe = ("import sys\n"
             "from wsnloc.metrics.stats import mean_ci95\n"
             "from wsnloc.experiments.claims import unpaired\n"
             "mean_ci95([1.0, 2.0, 3.0]); unpaired([1.0, 2.0, 3.0], [2.0, 3.0, 5.0, 7.0], '<', 'x')\n"
             "print(' '.join(m for m in sys.modules if m.startswith('scipy')))")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == ""
