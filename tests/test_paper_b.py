"""Paper B: dead reckoning, steady-state and classical KF, against closed-form cases."""

import numpy as np
import pandas as pd
import pytest

from wsnloc.estimators import inertial, registry
from wsnloc.estimators.inertial import align_fixes
from wsnloc.estimators.run_data import RunData
from wsnloc import results
from wsnloc.experiments import paper_b
from wsnloc.filters.steady_state import fuse, steady_state_gain
from wsnloc.inertial.dead_reckoning import dead_reckon, static_bias
from wsnloc.metrics.tracking import score

DT = 0.2


def _piecewise_motion():
    """60 s at 5 Hz: accelerate east, cruise, brake, rotate 90 deg in place, drive north.

    Inputs are constant over each 0.2 s step (zero-order hold), so eq. 4 is exact.
    Returns the IMU table and the true positions at the sample times.
    """
    segments = [  # (duration s, body ax m/s^2, yaw rate rad/s)
        (2.0, 0.0, 0.0), (2.0, 0.15, 0.0), (20.0, 0.0, 0.0), (2.0, -0.15, 0.0),
        (5.0, 0.0, np.pi / 10), (2.0, 0.1, 0.0), (25.0, 0.0, 0.0), (2.0, -0.1, 0.0)]
    ax = np.concatenate([np.full(int(round(d / DT)), a) for d, a, _ in segments])
    gz = np.concatenate([np.full(int(round(d / DT)), w) for d, _, w in segments])
    n = len(ax)
    t = np.arange(n + 1) * DT
    x, y, v, heading = np.zeros(n + 1), np.zeros(n + 1), 0.0, 0.0
    for k in range(n):                      # exact kinematics of the held inputs
        x[k + 1] = x[k] + np.cos(heading) * (v * DT + 0.5 * ax[k] * DT**2)
        y[k + 1] = y[k] + np.sin(heading) * (v * DT + 0.5 * ax[k] * DT**2)
        v += ax[k] * DT
        heading += gz[k] * DT
    imu = pd.DataFrame({"t": t, "ax": np.append(ax, 0.0), "ay": 0.0, "az": 9.81, "gz": np.append(gz, 0.0)})
    return imu, x, y


def test_dead_reckoning_follows_a_known_trajectory_within_1cm_over_60s():
    imu, x, y = _piecewise_motion()
    assert imu["t"].iloc[-1] == pytest.approx(60.0)
    dr = dead_reckon(imu, 0.0, 0.0, 0.0)
    assert np.hypot(dr["x"] - x, dr["y"] - y).max() < 0.01
    assert (x[-1], y[-1]) == pytest.approx((0.3 + 6.0 + 0.3, 0.2 + 5.0 + 0.2), abs=1e-9)   # ramps + cruise legs


def test_dead_reckoning_converges_on_a_smooth_turn():
    """Smooth speed ramp onto a 2 m circle: eq. 4 holds the inputs over a step, a first-order
    scheme, so halving the step about halves the error (3 cm at 5 Hz over 30 s, 1.4 turns)."""
    r, ramp = 2.0, 4.0

    def errors(step):
        t = np.arange(0.0, 30.0 + 1e-9, step)
        v = np.where(t < ramp, 0.15 * (1 - np.cos(np.pi * t / ramp)), 0.3)
        a = np.where(t < ramp, 0.15 * np.pi / ramp * np.sin(np.pi * t / ramp), 0.0)
        s = np.where(t < ramp, 0.15 * (t - ramp / np.pi * np.sin(np.pi * t / ramp)), 0.15 * ramp + 0.3 * (t - ramp))
        imu = pd.DataFrame({"t": t, "ax": a, "ay": v**2 / r, "az": 9.81, "gz": v / r})
        dr = dead_reckon(imu, 0.0, 0.0, 0.0)
        return np.hypot(dr["x"] - r * np.sin(s / r), dr["y"] - r * (1 - np.cos(s / r))).max()

    coarse, fine = errors(0.2), errors(0.1)
    assert fine < 0.6 * coarse and coarse < 0.05


def _loop_dead_reckon(imu, x0, y0, heading0):
    """dead_reckon as it was: the step-by-step loop (the reference the cumsum form must equal)."""
    t, ax, ay, gz = (imu[c].to_numpy(float) for c in ("t", "ax", "ay", "gz"))
    n = len(t)
    x, y, vx, vy, heading = (np.zeros(n) for _ in range(5))
    if n:
        x[0], y[0], heading[0] = x0, y0, heading0
    for k in range(n - 1):
        dt = t[k + 1] - t[k]
        mid = heading[k] + 0.5 * gz[k] * dt
        c, s = np.cos(mid), np.sin(mid)
        a_x, a_y = c * ax[k] - s * ay[k], s * ax[k] + c * ay[k]
        x[k + 1] = x[k] + vx[k] * dt + 0.5 * a_x * dt * dt
        y[k + 1] = y[k] + vy[k] * dt + 0.5 * a_y * dt * dt
        vx[k + 1] = vx[k] + a_x * dt
        vy[k + 1] = vy[k] + a_y * dt
        heading[k + 1] = heading[k] + gz[k] * dt
    return np.column_stack([t, x, y, vx, vy, heading])


@pytest.mark.parametrize("n", [0, 1, 2, 700])
def test_dead_reckoning_equals_the_step_by_step_loop_bitwise(n):
    """The sequential cumsums add the same rounded terms in the same order as the loop."""
    rng = np.random.default_rng(n)
    imu = pd.DataFrame({"t": np.cumsum(rng.uniform(0.15, 0.25, n)), "ax": rng.normal(0, 0.3, n),
                        "ay": rng.normal(0, 0.3, n), "az": 9.81, "gz": rng.normal(0, 0.2, n)})
    got = dead_reckon(imu, 3.0, -1.0, 0.7)
    assert list(got.columns) == ["t", "x", "y", "vx", "vy", "heading"]
    assert got.to_numpy().tobytes() == _loop_dead_reckon(imu, 3.0, -1.0, 0.7).tobytes()


def test_static_bias_is_removed():
    imu, x, y = _piecewise_motion()
    biased = imu.assign(ax=imu["ax"] + 0.02, ay=imu["ay"] - 0.01, gz=imu["gz"] + 0.003)
    bias = static_bias(biased, 1.8)                       # the first 2 s are at rest
    assert (bias.ax, bias.ay, bias.gz) == pytest.approx((0.02, -0.01, 0.003))
    dr = dead_reckon(biased, 0.0, 0.0, 0.0, bias)
    assert np.hypot(dr["x"] - x, dr["y"] - y).max() < 0.01
    assert np.hypot(*(dead_reckon(biased, 0.0, 0.0, 0.0)[["x", "y"]].to_numpy()[-1] - (x[-1], y[-1]))) > 1.0


def test_dare_gain_is_the_limit_of_the_classical_gain():
    Q, R = np.diag([0.01, 0.02]), np.diag([1.0, 0.5])
    P = np.diag([5.0, 5.0])
    for _ in range(500):
        P = P + Q
        K = P @ np.linalg.inv(P + R)
        P = (np.eye(2) - K) @ P @ (np.eye(2) - K).T + K @ R @ K.T
    np.testing.assert_allclose(steady_state_gain(Q, R), K, atol=1e-12)


def test_scalar_dare_gain_closed_form():
    """For A = H = 1: P = (q + sqrt(q^2 + 4 q r)) / 2, K = P / (P + r)."""
    q, r = 0.04, 1.0
    p = (q + np.sqrt(q * q + 4 * q * r)) / 2
    assert steady_state_gain([[q]], [[r]])[0, 0] == pytest.approx(p / (p + r))


def test_steady_state_filter_matches_a_hand_computed_sequence():
    gain = np.diag([0.5, 0.25])
    displacements = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    fixes = np.array([[3.0, 2.0], [np.nan, np.nan], [2.0, 2.0]])
    out = fuse(displacements, fixes, (0.0, 0.0), np.eye(2), np.eye(2), gain=gain)
    # step 1: predict (1, 0); update x: 1 + 0.5 (3 - 1) = 2, y: 0 + 0.25 (2 - 0) = 0.5
    # step 2: predict (3, 0.5), no fix
    # step 3: predict (3, 2.5); update x: 3 + 0.5 (2 - 3) = 2.5, y: 2.5 + 0.25 (2 - 2.5) = 2.375
    np.testing.assert_allclose(out, [[0, 0], [2.0, 0.5], [3.0, 0.5], [2.5, 2.375]])


def test_classical_filter_converges_to_the_steady_state_filter():
    rng = np.random.default_rng(2)
    n = 400
    displacements = rng.normal(0, 0.1, (n, 2))
    fixes = np.cumsum(displacements, axis=0) + rng.normal(0, 1.0, (n, 2))
    Q, R = np.eye(2) * 0.01, np.eye(2)
    ss = fuse(displacements, fixes, (0, 0), Q, R, gain=steady_state_gain(Q, R))
    kf = fuse(displacements, fixes, (0, 0), Q, R, P0=np.eye(2) * 10.0)
    assert np.abs(ss[-50:] - kf[-50:]).max() < 1e-6
    assert np.abs(ss[1] - kf[1]).max() > 0.1


def test_classical_filter_counts_the_updates_it_skips():
    """A fix that makes the update non-finite (an overflowing one) is skipped: the prior kept, as
    in every filter of the project, and counted in guards.skipped (filters.numerics), which the
    classical pipeline copies to its estimates' attrs for the diagnosis."""
    from wsnloc.filters.numerics import Guards

    displacements = np.array([[1.0, 0.0], [1.0, 0.0]])
    start = (-1e308, 0.0)
    fixes = np.array([[1e308, 0.0], [np.nan, np.nan]])             # innovation 2e308: overflows
    guards = Guards()
    with np.errstate(over="ignore", invalid="ignore"):
        out = fuse(displacements, fixes, start, np.eye(2), np.eye(2), P0=np.eye(2), guards=guards)
    assert guards.skipped == 1 and np.isfinite(out).all()
    np.testing.assert_array_equal(out[1], np.add(start, displacements[0]))     # the prior kept
    clean = Guards()
    fuse(displacements, -fixes, start, np.eye(2), np.eye(2), P0=np.eye(2), guards=clean)
    assert clean.skipped == 0


def _matrix_fuse(displacements, fixes, start, Q_step, R, gain=None, P0=None):
    """The former 2 x 2 matrix recursion of steady_state.fuse (the reference it must equal)."""
    p, P = np.asarray(start, dtype=float).copy(), np.zeros((2, 2)) if P0 is None else np.asarray(P0, float).copy()
    out, eye = [p], np.eye(2)
    for delta, z in zip(displacements, fixes):
        p, P = p + delta, P + Q_step
        if np.all(np.isfinite(z)):
            if gain is None:
                K = P @ np.linalg.inv(P + R)
                P = (eye - K) @ P @ (eye - K).T + K @ R @ K.T
            else:
                K = gain
            p = p + K @ (z - p)
        out.append(p)
    return np.array(out)


@pytest.mark.parametrize("q, r, p0", [((0.0025, 0.0025), (1.0, 1.0), (0.0, 0.0)),
                                      ((0.01, 0.003), (0.7, 2.5), (10.0, 0.5))])
def test_per_axis_filters_equal_the_matrix_recursion_bitwise(q, r, p0):
    """Diagonal Q, R, P0 and gain: the steady-state filter's per-axis float loops are the matrix
    products' operations on a diagonal gain, and the classical filter (filters.kalman's predict
    and joseph_update with F = H = I) adds only exact zeros, so the positions are bitwise the
    2 x 2 recursion's (fixes missing in one coordinate, or both, are not used)."""
    rng = np.random.default_rng(5)
    n = 500
    displacements = rng.normal(0, 0.1, (n, 2))
    fixes = np.cumsum(displacements, axis=0) + rng.normal(0, 1.0, (n, 2))
    fixes[rng.random(n) < 0.5] = np.nan
    fixes[rng.random(n) < 0.1, 1] = np.nan
    Q, R, P0 = np.diag(q), np.diag(r), np.diag(p0)
    gain = steady_state_gain(Q * 2.5, R)
    for kwargs in ({"gain": gain}, {"P0": P0}):
        got = fuse(displacements, fixes, (1.5, -2.0), Q, R, **kwargs)
        assert got.tobytes() == _matrix_fuse(displacements, fixes, (1.5, -2.0), Q, R, **kwargs).tobytes()
    assert fuse(displacements, fixes, (0, 0), Q, R).tobytes() == \
        _matrix_fuse(displacements, fixes, (0, 0), Q, R, P0=np.zeros((2, 2))).tobytes()


def test_fuse_refuses_coupled_axes():
    with pytest.raises(ValueError, match="diagonal"):
        fuse(np.zeros((2, 2)), np.zeros((2, 2)), (0, 0), np.eye(2), np.eye(2), gain=[[0.5, 0.1], [0.0, 0.5]])


def test_steady_state_gain_is_cached_per_setting_and_returned_as_a_copy():
    Q, R = np.eye(2) * 0.01, np.eye(2)
    first = steady_state_gain(Q, R)
    first[:] = 0.0
    np.testing.assert_array_equal(steady_state_gain(Q.tolist(), R), steady_state_gain(Q, R))
    assert steady_state_gain(Q, R)[0, 0] > 0 and steady_state_gain(Q * 4, R)[0, 0] > steady_state_gain(Q, R)[0, 0]


def test_fixes_are_aligned_to_the_step_they_arrive_in():
    steps = np.array([0.0, 0.2, 0.4, 0.6])
    fixes = pd.DataFrame({"t": [0.2, 0.5, 0.9], "x": [1.0, 2.0, 3.0], "y": [0.0, np.nan, 0.0]})
    aligned = align_fixes(steps, fixes)
    assert aligned[0].tolist() == [1.0, 0.0] and np.isnan(aligned[1:]).all()
    nan_time = pd.DataFrame({"t": [np.nan, 0.3], "x": [1.0, 2.0], "y": [0.0, 5.0]})    # dropped as dropna() drops it
    assert align_fixes(steps, nan_time)[1].tolist() == [2.0, 5.0] and np.isnan(align_fixes(steps, nan_time)[0]).all()


SPEC_B = {"scenarios": ["newcom/constant"],   # experiments.paper_b as in config/config.yaml
          "parameters": {"anchors": "UWB=10", "epoch_s": 0.5, "max_range_m": 50.0, "static_start_s": 4.0,
                         "process_sigma_m": 0.05, "fix_sigma_m": 1.0},
          "estimators": {"uwb": {"estimator": "minmax"}, "imu": {"estimator": "dead_reckoning"},
                         "sskf": {"estimator": "dr_sskf"}, "kf": {"estimator": "dr_kf"}}}


def test_paper_b_on_a_simulated_run(campaign, simulated_run):
    from wsnloc.io.newcom import ingest_run
    from wsnloc.signal.resample import resample_imu

    tables, _ = ingest_run(simulated_run, campaign)
    imu = resample_imu(tables["imu"], 5.0, 500.0, 0.1, 8.0)
    data = RunData(dict(tables, imu_5hz=imu), campaign)
    estimates = paper_b.run(data, SPEC_B, "newcom/constant")
    # the former frame: each method's registry.run (t, x, y) with its method assigned, concatenated
    base = dict(SPEC_B["parameters"], measurements="toa")
    former = [registry.run(name, data, {k: v for k, v in base.items() if k in {p.name for p in registry.get(name).params}},
                           where="experiments.paper_b")[["t", "x", "y"]].assign(method=method)
              for method, name in (("uwb", "minmax"), ("imu", "dead_reckoning"), ("sskf", "dr_sskf"), ("kf", "dr_kf"))]
    pd.testing.assert_frame_equal(estimates, score(pd.concat(former, ignore_index=True), tables["truth"]),
                                  check_exact=True)
    # the classical KF's guards reach its estimates' attrs and the diagnosis (none acted on this run)
    from wsnloc.diagnosis import diagnose_run

    p_kf = {k: v for k, v in base.items() if k in {p.name for p in registry.get("dr_kf").params}}
    kf = registry.run("dr_kf", data, p_kf, where="experiments.paper_b")
    assert kf.attrs["skipped"] == 0 and diagnose_run(data, kf, p_kf)["skipped"] == 0
    assert inertial.floor_input(data, 4.0) is inertial.floor_input(data, 4.0)      # built once per run
    metrics = paper_b.run_metrics(estimates, tables["truth"]).set_index("method")
    assert set(metrics.index) == {"uwb", "imu", "sskf", "kf"}
    assert metrics.loc["sskf", "rmse"] < metrics.loc["uwb", "rmse"] < 2.0
    paper = {"rmse_m": [{"row": "UWB only (Min-Max)", "simulation": 3.21, "real": 3.25, "max_real": "> 5"}]}
    rows = results.frame(paper_b.results_rows(metrics.reset_index(), "newcom/constant", paper, False))
    uwb = rows[(rows["table"] == "RMSE") & (rows["row"] == "UWB only (Min-Max)")]
    assert uwb["paper_value"].iloc[0] == 3.25
    claims = paper_b.claims({"newcom/constant": metrics.reset_index().assign(run="run-01")})
    assert [c["claim"] for c in claims][0].startswith("Fusion beats")
    assert all(c["verdict"] == "inconclusive" for c in claims)     # one run: no interval


def test_no_scenario_of_paper_b_takes_a_bias_estimate():
    """config/config.yaml: paper B's cart is "continuously moving" (seed 001 V.A): no rest to take a
    bias over on its real-data scenario, and its simulated accelerometer has no bias: static_start_s
    is 0 for every method that has it, and the UWB preliminary filter is off (seed 001 has none)."""
    from wsnloc.config import read_yaml
    from wsnloc.experiments import cells
    from wsnloc.validation import validate_config

    from conftest import ROOT

    spec = validate_config(read_yaml(ROOT / "config" / "config.yaml"), ROOT / "config" / "schema.yaml")["experiments"]["paper_b"]
    for method in ("imu", "sskf", "kf"):
        assert cells.params(spec, method, spec["simulation_scenarios"][0], "paper_b")["static_start_s"] == 0.0
        assert cells.params(spec, method, spec["scenarios"][0], "paper_b")["static_start_s"] == 0.0
    assert cells.params(spec, "uwb", spec["scenarios"][0], "paper_b")["preliminary_filter"] is False


def test_bias_estimate_adds_error_on_the_bias_free_simulated_accelerometer(campaign):
    """Paper B's simulated unit (noise model snr) has no bias: estimating one over the first
    4 s at rest turns the mean of 20 noise samples into a constant acceleration error, which
    dead reckoning integrates twice."""
    from wsnloc.analysis.imu_snr import dead_reckoning_rmse

    resample = {"rate_hz": 5.0, "grid_rate_hz": 500.0, "max_gap_s": 0.1, "kaiser_beta": 8.0}
    with_estimate, without = (
        [dead_reckoning_rmse(campaign, "b_simulation", 60.0, run, 20130101, resample, bias_s) for run in (1, 2, 3)]
        for bias_s in (4.0, 0.0))
    assert np.mean(without) < np.mean(with_estimate)
