"""The simulator's vectorised paths against step-by-step references: same floats, same bytes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wsnloc.sim import trajectory
from wsnloc.sim.logs import format_rows


def _reference_variable_speed(length, rng, static_start_s, ramp_interval_s, speed_range_mps,
                              max_accel_mps2, stop_s, static_end_s):
    """The controller integrated one 1 ms step at a time (the simulator's former loop)."""
    low, high = speed_range_mps
    stops = [length / 2.0, length]
    dt, a_max = trajectory.STEP_S, max_accel_mps2
    rest_start = int(round(static_start_s / dt))
    s_list, v_list, a_list = [0.0] * rest_start, [0.0] * rest_start, [0.0] * rest_start
    s, v, t_move, stop_index = 0.0, 0.0, 0.0, 0
    target = rng.uniform(low, high)
    steps, budget = 0, int(10 * length / low / dt)
    while steps < budget:
        steps += 1
        remaining = stops[stop_index] - s
        if remaining <= 1e-6 and v <= a_max * dt:
            s, v = stops[stop_index], 0.0
            if stop_index == len(stops) - 1:
                break
            stop_index += 1
            hold = min(int(round(stop_s / dt)), budget - steps)
            s_list += [s] * (hold + 1)
            v_list += [0.0] * (hold + 1)
            a_list += [0.0] * (hold + 1)
            steps += hold
            continue
        if t_move >= ramp_interval_s:
            target, t_move = rng.uniform(low, high), 0.0
        braking = math.sqrt(2.0 * a_max * max(remaining, 0.0))
        a = min(max((min(target, braking) - v) / dt, -a_max), a_max)
        if remaining > 0 and v > 0 and v * v / (2 * remaining) > a_max:
            a = -v * v / (2 * remaining)
        t_move += dt
        s_list.append(s)
        v_list.append(v)
        a_list.append(a)
        s = min(s + v * dt + a * (0.5 * dt**2), length)
        v = max(v + a * dt, 0.0)
    rest_end = int(round(static_end_s / dt))
    return (np.array(s_list + [length] * rest_end), np.array(v_list + [0.0] * rest_end),
            np.array(a_list + [0.0] * rest_end))


@pytest.mark.parametrize("params", [
    (24.57, 5.0, 5.0, (0.1, 0.5), 0.3, 4.0, 5.0),        # newcom.yaml `variable`
    (10.0, 1.0, 2.0, (0.2, 1.0), 0.5, 1.0, 0.5),
    (3.0, 0.0, 0.7, (0.05, 0.3), 0.1, 0.0, 0.0),
    (5.0, 0.0, 0.3, (0.3, 0.3), 2.0, 2.0, 0.0),          # one target speed
    (2.0, 0.5, 0.0, (0.1, 0.5), 0.3, 0.5, 0.5),          # a new target every step
])
def test_variable_speed_is_the_step_by_step_integration_bit_for_bit(params):
    length, *rest = params
    for seed in range(3):
        rng_fast, rng_reference = np.random.default_rng(seed), np.random.default_rng(seed)
        traj = trajectory.variable_speed(length, rng_fast, *rest)
        s, v, a = _reference_variable_speed(length, rng_reference, *rest)
        for got, expected in ((traj.s, s), (traj.v, v), (traj.a, a)):
            assert got.shape == expected.shape and got.tobytes() == expected.tobytes()
        assert traj.t.tobytes() == (np.arange(len(s)) * trajectory.STEP_S).tobytes()
        assert rng_fast.bit_generator.state == rng_reference.bit_generator.state     # same draws


def test_steps_per_target_counts_the_float_clock():
    for ramp in (0.0, 0.001, 0.0015, 0.3, 5.0, 7.77):
        clock, count = 0.0, 0
        while clock < ramp:
            clock += trajectory.STEP_S
            count += 1
        assert trajectory._steps_per_target(ramp, 10**6) == count


def test_constant_acceleration_states_follow_the_recurrence():
    s, v = trajectory._constant_acceleration(1.25, 0.1, -0.3, 400)
    s_k, v_k = 1.25, 0.1
    for k in range(401):
        assert (s[k], v[k]) == (s_k, v_k)
        s_k, v_k = s_k + v_k * trajectory.STEP_S + -0.3 * (0.5 * trajectory.STEP_S**2), v_k + -0.3 * trajectory.STEP_S


def test_array_controller_equals_the_step_controller():
    """_accelerations (the steady-run check) and _acceleration (single steps) are one rule: the
    same float on every state, including the braking and clipped cases and the stop point."""
    rng = np.random.default_rng(3)
    stop, a_max, target = 12.0, 0.5, 0.8
    s = np.concatenate([rng.uniform(0.0, stop + 0.5, 3000), stop - np.logspace(-9, 0, 200), [stop, stop + 1e-9]])
    v = np.concatenate([rng.uniform(0.0, 1.5, 3000), rng.uniform(0.0, 0.2, 200), [0.0, 0.3]])
    expected = np.array([trajectory._acceleration(si, vi, target, stop, a_max) for si, vi in zip(s.tolist(), v.tolist())])
    assert np.array_equal(trajectory._accelerations(s, v, target, stop, a_max), expected)


def _hard_floats(rng):
    """Values at, beside and between decimal ties, signed zeros, tiny and large magnitudes."""
    x = np.concatenate([rng.normal(0, 1e5, 2000), rng.normal(0, 1, 2000), np.arange(-400, 400) / 16,
                        np.arange(-400, 400) * 0.0005,
                        [-0.0, 0.0, -0.0004, 0.0005, -0.0005, 1e-300, -1e-300, 0.9995, 99999.9995, 12345.0625]])
    return np.concatenate([x, np.nextafter(x, np.inf), np.nextafter(x, -np.inf)])


@pytest.mark.parametrize("decimals", [0, 1, 2, 3, 6])
def test_format_rows_writes_what_percent_formatting_writes(decimals):
    rng = np.random.default_rng(decimals)
    x = _hard_floats(rng)
    counts = rng.integers(-10**12, 10**12, len(x))
    expected = [f"%.{decimals}f %d %.3f" % row for row in zip(x.tolist(), counts.tolist(), x[::-1].tolist())]
    assert format_rows([(x, decimals), (counts, 0), (x[::-1], 3)]) == expected
    assert format_rows([(x[:0], decimals)]) == []


def test_format_rows_refuses_values_it_cannot_round_exactly():
    with pytest.raises(ValueError):
        format_rows([(np.array([2.0**50]), 3)])
