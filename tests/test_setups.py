"""The papers' set-ups read from their text (issue 29 item 3): paper B's own scenario, paper C's
tilted accelerometer, no unsourced rests."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from wsnloc.sim import imu, trajectory


def test_paper_b_scenario_is_18_m_continuously_moving(newcom):
    """Seed 001 §V.A: a path of about 18 m, the cart continuously moving at 0.1-0.5 m/s."""
    for scenario in ("b_real", "b_simulation"):
        spec = newcom.section("scenarios", scenario)
        traj = trajectory.for_scenario(spec, newcom.path.length, np.random.default_rng(3))
        assert traj.s[-1] == pytest.approx(18.0)
        moving = traj.v > 0.01
        # at rest only while starting from 0 and braking onto the end point: well below 1% of the run
        assert 1.0 - moving.mean() < 0.01
        first, last = np.flatnonzero(moving)[[0, -1]]
        assert np.all(moving[first:last + 1])                 # no stop between start and end
        assert traj.v[moving].mean() == pytest.approx(0.29, abs=0.05)


def test_stop_s_zero_means_no_stop_half_way():
    with_stop = trajectory.variable_speed(10.0, np.random.default_rng(1), 0.0, 2.0, (0.2, 0.4), 0.3, 1.0, 0.0)
    without = trajectory.variable_speed(10.0, np.random.default_rng(1), 0.0, 2.0, (0.2, 0.4), 0.3, 0.0, 0.0)
    half = lambda traj: np.flatnonzero((traj.v < 1e-9) & (np.abs(traj.s - 5.0) < 1e-6))   # noqa: E731
    assert len(half(with_stop)) >= 1000                        # 1 s held at 5 m
    assert len(half(without)) == 0


def test_path_length_must_fit_the_campaign_path(newcom):
    spec = dict(newcom.section("scenarios", "b_real"), path_length_m=30.0)
    with pytest.raises(ValueError, match="path_length_m"):
        trajectory.for_scenario(spec, newcom.path.length, np.random.default_rng(0))


def test_cricket_runs_have_no_rest(cricket):
    """Seed 002 mentions no rest: the cart moves from the first to the last sample."""
    for scenario in ("speed_20", "speed_40", "speed_60"):
        spec = cricket.section("scenarios", scenario)
        traj = trajectory.for_scenario(spec, cricket.path.length, np.random.default_rng(0))
        assert np.mean(traj.v < 0.01) < 0.01


def test_tilt_angles_have_the_configured_statistics(cricket):
    """Pitch/roll = per-run mount tilt + floor slope with exponential autocorrelation."""
    spec = dict(cricket.section("imu"), mount_tilt_sigma_deg=0.0)
    s = np.arange(0.0, 2000.0, 0.01)
    pitch, roll = imu.tilt_angles(s, spec, np.random.default_rng(2))
    sigma = np.deg2rad(spec["floor_slope_sigma_deg"])
    assert np.std(pitch) == pytest.approx(sigma, rel=0.1)
    assert np.std(roll) == pytest.approx(sigma, rel=0.1)
    lag = int(round(spec["floor_slope_correlation_m"] / 0.01))
    corr = np.corrcoef(pitch[:-lag], pitch[lag:])[0, 1]
    assert corr == pytest.approx(np.exp(-1.0), abs=0.08)       # sigma^2 exp(-|ds| / ell) at ds = ell
    assert abs(np.corrcoef(pitch, roll)[0, 1]) < 0.1
    mounted = dict(spec, mount_tilt_sigma_deg=1.0, floor_slope_sigma_deg=0.0)
    pitch, roll = imu.tilt_angles(s[:10], mounted, np.random.default_rng(2))
    assert np.ptp(pitch) == 0.0 and pitch[0] != 0.0            # a constant per run
    level = {k: v for k, v in spec.items() if k not in ("mount_tilt_sigma_deg", "floor_slope_sigma_deg")}
    assert not np.any(imu.tilt_angles(s[:10], level, np.random.default_rng(2)))


def test_tilt_leaks_gravity_into_the_horizontal_axes():
    g = 9.80665
    force = np.array([[0.1, 0.0, g], [0.0, 0.2, g]])
    pitch, roll = np.deg2rad([1.0, 0.0]), np.deg2rad([0.0, -2.0])
    out = imu.tilt_leakage(force, pitch, roll, g)
    assert out[0] == pytest.approx([0.1 + g * np.sin(np.deg2rad(1.0)), 0.0, g * np.cos(np.deg2rad(1.0))])
    assert out[1] == pytest.approx([0.0, 0.2 + g * np.sin(np.deg2rad(2.0)), g * np.cos(np.deg2rad(2.0))])
    assert np.linalg.norm(out[1] - [0.0, 0.2, 0.0]) == pytest.approx(g)   # gravity's magnitude is kept


def test_cricket_accelerometer_error_is_in_band(cricket):
    """The tilt leakage survives the 5 Hz output: at 0.2-0.6 m/s over 0.3 m the slope varies
    at 0.7-2 Hz, below the 2.5 Hz Nyquist frequency of the 5 Hz stream."""
    spec = cricket.section("imu")
    fs, speed = 500.0, 0.4
    t = np.arange(0.0, 120.0, 1.0 / fs)
    pitch, _ = imu.tilt_angles(speed * t, dict(spec, mount_tilt_sigma_deg=0.0), np.random.default_rng(5))
    leak = 9.80665 * np.sin(pitch)
    spectrum = np.abs(np.fft.rfft(leak - leak.mean())) ** 2
    freq = np.fft.rfftfreq(len(leak), 1.0 / fs)
    assert spectrum[freq < 2.5].sum() / spectrum.sum() > 0.8


def test_multilateration_without_refinement_is_the_closed_form_linear_solution():
    """Seed 004 §3.2, "simple geometric techniques": refine=False returns the linearised least squares
    (subtract the last circle, solve A p = b), which differs from the Gauss-Newton fix on noisy ranges."""
    from wsnloc.geometry.lateration import multilateration

    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]])
    truth = np.array([3.0, 2.0])
    ranges = np.hypot(*(anchors - truth).T) + np.array([0.3, -0.2, 0.4, 0.1])
    ref, d_ref = anchors[-1], ranges[-1]
    A = 2.0 * (ref - anchors[:-1])
    b = ranges[:-1] ** 2 - d_ref**2 - np.sum(anchors[:-1] ** 2, axis=1) + np.sum(ref**2)
    closed_form = np.linalg.lstsq(A, b, rcond=None)[0]
    assert multilateration(anchors, ranges, refine=False) == pytest.approx(closed_form, abs=1e-9)
    refined = multilateration(anchors, ranges, refine=True)
    assert np.linalg.norm(refined - closed_form) > 1e-3
    cost = lambda p: np.sum((np.hypot(*(anchors - p).T) - ranges) ** 2)   # noqa: E731
    assert cost(refined) < cost(closed_form)


def test_registry_multilateration_refine_option_reaches_the_solver():
    from wsnloc.estimators import registry

    assert registry.get("multilateration").resolve({})["refine"] is True
    assert registry.get("multilateration").resolve({"refine": False})["refine"] is False
    assert "refine" not in registry.get("minmax").resolve({})


def test_kalman_over_fixes_with_speed_input_uses_the_velocity_algorithms_speed():
    """Paper D §4.2: the KF also takes the velocity algorithm's speed. On a straight constant-speed
    track with noise-free fixes and a KF that starts at rest, the speed measurement (exactly the
    true speed here) pulls the speed state to the truth faster than position updates alone."""
    from wsnloc.estimators import trackers

    t = np.arange(0.0, 10.0, 0.5)
    fixes = pd.DataFrame({"t": t, "x": 0.4 * t, "y": 0.0})
    plain, fed = (trackers.fix_tracks([trackers.FixSource.of(fixes, velocity)], 0.5, 0.1, 0.5, 0.5, 0.05)[0].frame()
                  for velocity in (None, (6, "raw")))
    early = slice(2, 6)
    assert np.abs(fed["x"] - fixes["x"])[early].mean() < np.abs(plain["x"] - fixes["x"])[early].mean()
    assert not np.allclose(plain["x"], fed["x"])
    assert (plain["n_meas"].iloc[1:] == 1).all() and (fed["n_meas"].iloc[3:] == 2).all()


def test_speed_measurement_jacobian_is_numerical():
    from wsnloc.estimators.trackers import _position_and_speed, _position_and_speed_jacobian

    state = np.array([1.0, 2.0, 0.3, -0.4])
    numeric = np.column_stack([(_position_and_speed(state + e) - _position_and_speed(state - e)) / 2e-6
                               for e in np.eye(4) * 1e-6])
    assert _position_and_speed_jacobian(state) == pytest.approx(numeric, abs=1e-8)


def test_heading_from_fixes_is_the_direction_of_the_first_metre_despite_an_outlier():
    """No true initial heading for the PVA input: it is measured from the first fixes."""
    from wsnloc.estimators.inertial import heading_from_fixes

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 8.0, 0.5)
    direction = np.deg2rad(30.0)
    x = 1.0 + 0.3 * t * np.cos(direction) + rng.normal(0, 0.02, len(t))
    y = 1.0 + 0.3 * t * np.sin(direction) + rng.normal(0, 0.02, len(t))
    x[1] += 1.5                                               # one reflected range: a fix 1.5 m off
    heading = heading_from_fixes(pd.DataFrame({"t": t, "x": x, "y": y}))
    assert np.rad2deg(heading) == pytest.approx(30.0, abs=5.0)
    assert heading_from_fixes(pd.DataFrame({"t": t, "x": 1.0, "y": 1.0})) is None   # never moves 1 m


def test_why_formulas_and_every_non_holding_claim_gets_a_mechanism():
    """claims.json `why` (issue 29 item 4): the fusion bounds used in the mechanisms, and a claim that
    does not hold without a computed mechanism is refused."""
    from wsnloc.experiments import why
    from wsnloc.metrics.verdicts import DOES_NOT_HOLD, HOLDS

    assert why.independent_combination(0.3, 0.4) == pytest.approx(1.0 / np.sqrt(1 / 0.09 + 1 / 0.16))
    assert why.barycentre(0.5, 2.0) == pytest.approx(np.sqrt(0.25**2 + 1.0**2))
    rng = np.random.default_rng(0)
    runs = [f"run-{k:02d}" for k in range(1, 6)]
    per_run = pd.DataFrame([{"method": m, "rmse": level + rng.normal(0, 0.01), "max": 3 * level, "n": 300.0, "run": r}
                            for m, level in (("uwb", 1.0), ("imu", 20.0), ("sskf", 5.0), ("kf", 5.01)) for r in runs])
    records = [{"claim": "Fusion beats both UWB only and IMU only", "verdict": DOES_NOT_HOLD},
               {"claim": "The classical KF is somewhat better than the steady-state KF", "verdict": HOLDS}]
    out = why.explain_b(records, {"newcom/b_real": per_run}, {"newcom/b_real": 0.0}, {"newcom/b_real": 0.03})
    assert "IMU only 20.00" in out[0]["why"] and "b T^2 / 2 = 54 m over the 60 s run" in out[0]["why"]
    assert "a 0.03 m/s^2 turn-on bias" in out[0]["why"]         # the campaign's sigma, as given
    unbiased = why.explain_b(records, {"newcom/b_real": per_run}, {"newcom/b_real": 0.0}, {"newcom/b_real": 0.0})
    assert "turn-on bias" not in unbiased[0]["why"]
    assert "why" not in out[1]
    with pytest.raises(KeyError, match="no computed mechanism"):
        why._attach([{"claim": "unknown", "verdict": DOES_NOT_HOLD}], {})


def test_paper_a_speed_mechanism_reads_the_campaign_accelerations_and_the_model_sigma(newcom):
    """Paper A's constant-vs-variable `why` states each profile's peak acceleration from the campaign
    (ramp speed / time, or the variable profile's limit) against the PV model's sigma, not typed values."""
    from wsnloc.experiments import why
    from wsnloc.metrics.verdicts import DOES_NOT_HOLD

    sections = {f"newcom/{s}": newcom.section("scenarios", s) for s in ("constant", "variable")}
    peaks = {label: trajectory.peak_acceleration(section) for label, section in sections.items()}
    assert peaks["newcom/constant"] == pytest.approx(sections["newcom/constant"]["speed_mps"]
                                                     / sections["newcom/constant"]["accel_time_s"])
    assert peaks["newcom/variable"] == sections["newcom/variable"]["max_accel_mps2"]
    rows = ["TOA 12", "TOA 9", "RSS 21", "RSS 17", "hybrid 33", "hybrid 26"]
    per_run = pd.DataFrame([{"table": t, "row": r, "rmse": 1.0, "rmse_moving": 1.0, "run": f"run-0{k}"}
                            for t in ("Table I", "Table II") for r in rows for k in (1, 2)])
    claim = "Constant speed is tracked better than variable speed"
    records = [{"claim": claim, "verdict": DOES_NOT_HOLD}]
    metrics = {label: per_run for label in sections}
    sigmas = {label: 0.5 for label in sections}
    within = why.explain_a(records, metrics, rows, peaks, sigmas)[0]["why"]
    assert f"newcom/variable {peaks['newcom/variable']:.2g} <= 0.5 m/s^2" in within
    assert "models both profiles" in within
    beyond = why.explain_a([dict(records[0])], metrics, rows, {**peaks, "newcom/variable": 0.9}, sigmas)[0]["why"]
    assert "newcom/variable 0.9 > 0.5 m/s^2" in beyond and "lags on the steepest ramps" in beyond
    # each scenario against its own sigma (a per-scenario override), not the first scenario's
    own = why.explain_a([dict(records[0])], metrics, rows, {**peaks, "newcom/variable": 0.9},
                        {**sigmas, "newcom/variable": 1.0})[0]["why"]
    assert "newcom/variable 0.9 <= 1 m/s^2" in own and "models both profiles" in own


@pytest.mark.parametrize("rho", [np.exp(-0.01 / 0.3), 0.5, 0.999])
def test_slope_recursion_gives_the_floats_of_lfilter(rho):
    """The floor slope's AR(1) recursion (imu._ar1, numpy only) and scipy.signal.lfilter: same floats."""
    from scipy.signal import lfilter

    shocks = np.random.default_rng(4).normal(0.0, 0.004, 5000)
    assert np.array_equal(imu._ar1(shocks, rho), lfilter([1.0], [1.0, -rho], shocks))
