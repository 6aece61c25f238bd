"""The simulator's vectorised paths against step-by-step references: same floats, same bytes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wsnloc.sim import imu, newcom, rss, trajectory, uwb_channel
from wsnloc.sim.logs import _sorted, format_text


def _reference_variable_speed(length, rng, static_start_s, ramp_interval_s, speed_range_mps,
                              max_accel_mps2, stop_s, static_end_s):
    """The controller integrated one 1 ms step at a time (the simulator's former loop)."""
    low, high = speed_range_mps
    stops = [length / 2.0, length] if stop_s > 0 else [length]      # stop_s 0: no stop half-way
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
    (24.57, 5.0, 5.0, (0.1, 0.5), 0.3, 4.0, 5.0),        # a stop half-way
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
def test_format_text_writes_what_percent_formatting_writes(decimals):
    rng = np.random.default_rng(decimals)
    x = _hard_floats(rng)
    counts = np.concatenate([rng.integers(-10**12, 10**12, len(x) - 4), [0, -1, 2**63 - 1, -(2**63 - 1)]])
    expected = "".join(f"%.{decimals}f %d %.3f\n" % row for row in zip(x.tolist(), counts.tolist(), x[::-1].tolist()))
    assert format_text([(x, decimals), (counts, 0), (x[::-1], 3)]) == expected
    assert format_text([(counts[:1], 0)]) == f"{counts[0]}\n"
    small = np.array([0.0004, -0.0, 0.5, -0.0015, 0.0])                # every value narrower than the decimals
    assert format_text([(small, decimals), (np.zeros(5, dtype=np.int64), 0)]) == \
        "".join(f"%.{decimals}f 0\n" % value for value in small.tolist())
    assert format_text([(x[:0], decimals)]) == ""


def test_format_text_refuses_values_it_cannot_write_exactly():
    with pytest.raises(ValueError):
        format_text([(np.array([2.0**50]), 3)])
    with pytest.raises(ValueError):
        format_text([(np.array([-(2**63)]), 0)])


def _reference_impulse_responses(model, rng, n_links):
    """The channel model as first written (rate array, nonzero, complex product)."""
    n_clusters = np.maximum(1, rng.poisson(model["mean_clusters"], n_links))
    width = int(n_clusters.max())
    gaps = rng.exponential(1.0 / model["cluster_rate_per_ns"], (n_links, width - 1))
    cluster_t = np.concatenate([np.zeros((n_links, 1)), np.cumsum(gaps, axis=1)], axis=1)
    clusters = (np.arange(width)[None, :] < n_clusters[:, None]) \
        & (cluster_t < uwb_channel.CLUSTER_SPAN * model["cluster_decay_ns"])
    energy_db = -10 * np.log10(np.e) * cluster_t / model["cluster_decay_ns"] \
        + rng.normal(0.0, model["cluster_sigma_db"], (n_links, width))
    omega = 10 ** (energy_db / 10)
    link, cluster = np.nonzero(clusters)
    beta, l1, l2 = model["ray_mixture_beta"], model["ray_rate_1_per_ns"], model["ray_rate_2_per_ns"]
    diffuse = bool(model.get("diffuse_first_cluster", False))
    decay = np.full(len(link), float(model["ray_decay_ns"]))
    if diffuse:
        decay[cluster == 0] = model["first_cluster_decay_ns"]
    shape = (len(link), int(uwb_channel.RAY_SPAN * decay.max() * max(l1, l2) * 1.3) + 10)
    rate = np.where(rng.random(shape) < beta, l1, l2)
    inter = rng.exponential(1.0, shape) / rate
    inter[:, 0] = 0.0
    tau = np.cumsum(inter, axis=1)
    row, ray = np.nonzero(tau < uwb_channel.RAY_SPAN * decay[:, None])
    tau, decay = tau[row, ray], decay[row]
    omega_ray = omega[link, cluster][row]
    mean_power = omega_ray / (decay * ((1 - beta) * l1 + beta * l2 + 1)) * np.exp(-tau / decay)
    if diffuse:
        rise, g1, chi = model["rise_ns"], model["first_cluster_decay_ns"], model["diffuse_chi"]
        first = cluster[row] == 0
        mean_power[first] = omega_ray[first] * (1 - chi * np.exp(-tau[first] / rise)) * np.exp(-tau[first] / g1) \
            * (g1 + rise) / (g1 * (g1 + rise * (1 - chi)))
    m = np.maximum(np.exp(rng.normal(model["nakagami_m0"], model["nakagami_sigma_m0"], len(row))), 0.5)
    if model.get("first_ray_m") is not None:
        m[ray == 0] = model["first_ray_m"]
    power = rng.gamma(m, mean_power / m)
    phase = rng.uniform(0.0, 2 * np.pi, len(row))
    magnitude = np.sqrt(power)
    return link[row], cluster_t[link, cluster][row] + tau, magnitude * np.cos(phase) + 1j * (magnitude * np.sin(phase))


@pytest.mark.parametrize("name", ["CM3", "CM4"])
def test_impulse_responses_and_taps_are_the_reference_bit_for_bit(campaign, name):
    """Same rays, same draws: the rng ends in the same state and the tap powers (what the
    detectors read) are the same floats; amplitudes equal up to the sign of a zero part."""
    spec = campaign.section("radio", "uwb")
    model = dict(spec["channel_models"][name])
    for seed, n_links in ((0, 1), (1, 37), (2, 512)):
        rng_fast, rng_reference = np.random.default_rng(seed), np.random.default_rng(seed)
        fast = uwb_channel.impulse_responses(model, rng_fast, n_links)
        reference = _reference_impulse_responses(model, rng_reference, n_links)
        assert rng_fast.bit_generator.state == rng_reference.bit_generator.state
        for got, expected in zip(fast[:2], reference[:2]):
            assert got.dtype == expected.dtype and got.tobytes() == expected.tobytes()
        assert np.array_equal(fast[2], reference[2])
        taps = [uwb_channel.tap_powers(*rays, spec["cir_tap_ns"], n_links) for rays in (fast, reference)]
        assert taps[0].tobytes() == taps[1].tobytes()


def _reference_vibration(t, v, spec, rng):
    """The vibration as first written: sin over (samples, tones), summed over the tone axis."""
    tones = np.asarray(spec["vibration_tones_hz"], dtype=float)
    amplitude = spec["vibration_mps2_at_ref_speed"] * np.sqrt(2.0 / len(tones)) * (v / spec["vibration_ref_speed_mps"])
    phases = rng.uniform(0.0, 2 * np.pi, (3, len(tones)))
    return np.column_stack([weight * amplitude * np.sin(2 * np.pi * tones[None, :] * t[:, None]
                                                        + phases[axis][None, :]).sum(axis=1)
                            for axis, weight in enumerate(spec["vibration_axis_weights"])])


@pytest.mark.parametrize("tones", [None, [21.0], [17.0, 23.0], [5.0, 9.0, 13.0, 17.0, 23.0, 29.0, 31.0, 37.0, 41.0]])
@pytest.mark.parametrize("n", [1, 2, 7, 5000])
def test_vibration_is_the_per_axis_formula_bit_for_bit(campaign, tones, n):
    """Moving samples: the same floats as the (samples, tones) formula; at rest (v = 0) the
    formula gives +-0, the fast path +0."""
    spec = dict(campaign.section("imu"))
    if tones is not None:
        spec["vibration_tones_hz"] = tones
    rng = np.random.default_rng(4)
    t = np.sort(rng.uniform(0.0, 120.0, n))
    v = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(0.0, 0.6, n))
    got = imu.vibration(t, v, spec, np.random.default_rng(9))
    expected = _reference_vibration(t, v, spec, np.random.default_rng(9))
    assert got.tobytes() == np.where(v[:, None] == 0.0, 0.0, expected).tobytes()


@pytest.mark.parametrize("seed", range(4))
def test_accelerometer_is_the_reference_sum_bit_for_bit(campaign, seed):
    """accel = ((f + bias) + noise) + vibration with the reference vibration, drawn in the same
    order: the same floats, and the rng ends in the same state (rest and motion mixed)."""
    spec = dict(campaign.section("imu"), noise_model="mems")
    g, n, fs = campaign.spec["gravity_mps2"], 4000, campaign.section("imu")["rate_hz"]
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    v = np.where((t > 2.0) & (t < 6.0), rng.uniform(0.0, 0.5, n), 0.0)
    force, yaw = imu.body_motion(v, rng.normal(0.0, 0.1, n), rng.normal(0.0, 0.2, n), g)
    rng_fast, rng_reference = np.random.default_rng(seed + 10), np.random.default_rng(seed + 10)
    accel, gyro = imu.sensor_readings(t, force, yaw, v, spec, g, rng_fast)
    bias = rng_reference.normal(0.0, spec["accel_bias_sigma_mps2"], 3)
    sigma = spec["accel_noise_ug_per_rthz"] * imu.MICRO_G * g * np.sqrt(fs / 2.0)
    expected = force + bias + rng_reference.normal(0.0, sigma, (n, 3)) + _reference_vibration(t, v, spec, rng_reference)
    assert accel.tobytes() == expected.tobytes()
    rng_reference.normal(0.0, spec["gyro_bias_sigma_dps"])
    rng_reference.normal(0.0, 1.0, n)
    assert rng_fast.bit_generator.state == rng_reference.bit_generator.state


def test_broadcast_lines_are_the_per_pair_formatting():
    rng = np.random.default_rng(6)
    ids = [f"Z{k:02d}" for k in range(1, 22)]
    times_ms = np.arange(50.0, 9000.0, 50.0)
    rssi = rng.integers(-110, 5, (len(times_ms), len(ids)))
    heard = rng.random(rssi.shape) < np.linspace(0.0, 0.9, len(times_ms))[:, None]   # first broadcast: none heard
    expected = []
    for b in range(len(times_ms)):
        pairs = [f"{ids[a]}:{rssi[b, a]:d}" for a in np.flatnonzero(heard[b]).tolist()]
        if pairs:
            expected.append(f"{int(times_ms[b]) + 10000} {(b + 1) % 256} {len(pairs)} " + " ".join(pairs))
    assert newcom._broadcast_lines(times_ms, heard, rssi, ids, 10000) == expected
    assert newcom._broadcast_lines(times_ms, heard & False, rssi, ids, 10000) == []
    one = np.zeros_like(heard)
    one[3, 20] = True                                      # a single pair, of the last anchor
    assert newcom._broadcast_lines(times_ms, one, rssi, ids, 0) == [f"{int(times_ms[3])} 4 1 Z21:{rssi[3, 20]:d}"]


def test_correlated_shadowing_is_the_recursion_bit_for_bit():
    """X_0 = sigma e_0, X_k = rho_k X_{k-1} + sqrt(1 - rho_k^2) sigma e_k, with rests (rho = 1)."""
    rng = np.random.default_rng(7)
    s = np.concatenate([np.zeros(50), np.cumsum(rng.uniform(0.0, 0.05, 400)), np.full(30, 9.0)])
    got = rss.correlated_shadowing(s, 5, 4.0, 2.0, np.random.default_rng(8))
    innovations = np.random.default_rng(8).normal(0.0, 4.0, (len(s), 5))
    rho = np.exp(-np.abs(np.diff(s, prepend=s[:1])) / 2.0)
    scale = np.sqrt(1.0 - rho**2)
    expected = [innovations[0]]
    for k in range(1, len(s)):                   # the former loop
        expected.append(rho[k] * expected[-1] + scale[k] * innovations[k])
    assert got.tobytes() == np.array(expected).tobytes()


def test_sorted_is_np_sort():
    rng = np.random.default_rng(10)
    jittered = np.arange(0.0, 2000.0, 2.0) + rng.normal(0.0, 0.02, 1000)
    reordered = np.arange(0.0, 20.0, 2.0) + rng.normal(0.0, 3.0, 10)
    for values in (jittered, reordered, np.repeat(reordered, 3), reordered[:1], reordered[:0]):
        assert _sorted(values).tobytes() == np.sort(values).tobytes()
