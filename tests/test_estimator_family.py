"""The registry's UKF, particle filter, RTS smoothers and sliding-window batch estimator:
noise-free geometry, agreement with filterpy on the same measurements, the smoother's
forward pass in both update modes, the particle filter's seed, robustness to outliers."""

import json

import numpy as np
import pandas as pd
import pytest
from filterpy.kalman import ExtendedKalmanFilter as FilterpyEKF
from filterpy.kalman import KalmanFilter as FilterpyKF
from filterpy.kalman import MerweScaledSigmaPoints
from filterpy.kalman import UnscentedKalmanFilter as FilterpyUKF

from synthetic import SQUARE, bursts, epoch_stamped_bursts, one_at_a_time, run_data, tables_for, walk
from test_estimators import CONFIGURED_RSS, TARGET, static_run
from test_smoother import _block_row
from wsnloc.cli import main
from wsnloc.estimators import registry
from wsnloc.estimators.measurements import MeasurementSource
from wsnloc.estimators.smoothing import ForwardPass
from wsnloc.filters.kalman import KalmanFilter
from wsnloc.filters.motion_models import constant_velocity, pva
from wsnloc.metrics.tracking import score
from wsnloc.studies import run_cell

NEW = ["ukf", "pf", "ekf_rts", "ukf_rts", "sliding_window"]


def noisy_walk(seed=8, seconds=30.0, noise_m=0.2):
    rng = np.random.default_rng(seed)
    times, ids = bursts(seconds, 0.5, SQUARE)
    return run_data(tables_for(times, ids, walk, SQUARE, noise_m=noise_m, rng=rng))


def final_error(estimates) -> float:
    return float(np.hypot(*(estimates[["x", "y"]].to_numpy()[-1] - TARGET)))


@pytest.mark.parametrize("name, params, tolerance_m", [
    ("ukf", {}, 1e-6), ("ukf", {"update": "sequential"}, 1e-6), ("ekf_rts", {}, 1e-6),
    ("ekf_rts", {"update": "sequential"}, 1e-6), ("ukf_rts", {"motion": "p"}, 1e-6), ("sliding_window", {}, 1e-6),
    ("ukf", {"measurements": "hybrid", **CONFIGURED_RSS}, 1e-6),
    # Monte Carlo: the particles keep the spread the process noise gives them between updates
    ("pf", {}, 0.1), ("pf", {"update": "sequential", "outlier_probability": 0.05}, 0.1),
    ("pf", {"measurements": "rss", "n_particles": 2000, **CONFIGURED_RSS}, 0.3),
])
def test_new_estimators_converge_to_a_static_target(name, params, tolerance_m):
    estimates = registry.run(name, static_run(seconds=120.0, rss=True), params)
    assert len(estimates) >= 200 and final_error(estimates) < tolerance_m


@pytest.mark.parametrize("name", ["ukf", "pf", "ekf_rts", "sliding_window"])
def test_new_estimators_start_away_from_the_truth_and_converge(name):
    """The first epoch's ranges carry 1 m noise, so the initiator's fix is off; the noise-free
    ranges after it must pull every estimator onto the target."""
    rng = np.random.default_rng(2)
    times, ids = bursts(60.0, 0.5, SQUARE)
    noise = np.where(times <= 0.5, 1.0, 0.0) * rng.normal(0.0, 1.0, len(times))   # a poor first epoch
    tables = tables_for(times, ids, TARGET, SQUARE)
    tables["ranges"]["range_m"] += noise
    initiator = registry.run("ekf", run_data(tables))[["x", "y"]].to_numpy()[0]
    assert np.hypot(*(initiator - TARGET)) > 0.2
    estimates = registry.run(name, run_data(tables), {"n_particles": 2000} if name == "pf" else {})
    assert final_error(estimates) < (0.05 if name == "pf" else 1e-3)


def test_sequential_smoother_and_filters_follow_a_noise_free_walk():
    """Sequential updates predict to the output time; the smoother also sees the turns ahead,
    so its worst error at the square's corners is well below the filter's."""
    times, ids = bursts(200.0, 0.5, SQUARE)
    data = run_data(tables_for(times, ids, walk, SQUARE))
    errors = {name: score(registry.run(name, data, {"update": "sequential"}), data.table("truth"))["error_m"]
              .iloc[20:] for name in ("ekf", "ukf", "pf", "ekf_rts")}
    for name, error in errors.items():
        assert np.nanmedian(error) < (0.05 if name == "pf" else 0.01), name
    assert np.nanmax(errors["ekf_rts"]) < 0.6 * np.nanmax(errors["ekf"])
    window = score(registry.run("sliding_window", data), data.table("truth"))["error_m"].iloc[20:]
    assert np.nanmedian(window) < 1e-6


def test_sequential_smoother_halves_the_filter_error_on_noisy_ranges_one_anchor_at_a_time():
    """Ranges one anchor at a time (8 Hz, sigma 0.3 m): each smoothed estimate also uses the
    ranges after it, so its error is well below the forward tracker's."""
    rng = np.random.default_rng(1)
    times, ids = one_at_a_time(300.0, 8.0, rng, SQUARE)
    data = run_data(tables_for(times, ids, walk, SQUARE, noise_m=0.3, rng=rng))
    tracker = score(registry.run("tracker", data), data.table("truth"))["error_m"].iloc[10:]
    smoothed = score(registry.run("ekf_rts", data, {"update": "sequential", "init_window_s": 4.0,
                                                    "initial_sigma_m": 2.0}), data.table("truth"))["error_m"].iloc[10:]
    assert np.nanmedian(smoothed) < 0.6 * np.nanmedian(tracker)
    assert np.nanpercentile(smoothed, 95) < 0.6 * np.nanpercentile(tracker, 95)


def _filterpy_epoch_pass(data, params):
    """filterpy's EKF on the registry's epoch models from the registry's start: (Xs, Ps, Fs, Qs)."""
    p = registry.get("ekf").resolve(params)
    start = registry.run("ekf", data, params)
    source = MeasurementSource(data, "toa", "all", p["range_sigma_m"], True, 100.0, None)
    grid = data.grid(0.5, True, 100.0)
    models = source.epoch_models(grid, 0.5)
    F, Q = constant_velocity(0.5, p["accel_sigma_mps2"])
    ref = FilterpyEKF(dim_x=4, dim_z=4)
    ref.x = np.array([start["x"].iloc[0], start["y"].iloc[0], 0.0, 0.0])
    ref.F, ref.Q = F, Q
    ref.P = np.diag([p["initial_sigma_m"] ** 2] * 2 + [p["initial_speed_sigma_mps"] ** 2] * 2)
    xs, Ps = [ref.x.copy()], [ref.P.copy()]
    for model in models[int(np.searchsorted(grid, start["t"].iloc[0])) + 1:]:
        ref.predict()
        ref.update(model.z, HJacobian=model.jacobian, Hx=model.h, R=model.R())
        xs.append(ref.x.copy())
        Ps.append(ref.P.copy())
    n = len(xs)
    return np.array(xs), np.array(Ps), np.repeat(F[None], n, axis=0), np.repeat(Q[None], n, axis=0), models, grid


def test_epoch_ekf_rts_equals_filterpys_rts_smoother_over_filterpys_ekf():
    params = {"accel_sigma_mps2": 0.4, "range_sigma_m": 0.2, "self_fit": "none"}
    data = noisy_walk()
    xs, Ps, Fs, Qs, _, _ = _filterpy_epoch_pass(data, params)
    smoothed, P_smoothed, _, _ = FilterpyKF(dim_x=4, dim_z=1).rts_smoother(xs, Ps, Fs, Qs)
    ours = registry.run("ekf_rts", data, params)
    assert len(ours) == len(xs)
    np.testing.assert_allclose(ours[["x", "y"]].to_numpy(), smoothed[:, :2], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours[["p_xx", "p_xy", "p_yy"]].to_numpy(),
                               P_smoothed[:, [0, 0, 1], [0, 1, 1]], rtol=0, atol=1e-9)
    forward = registry.run("ekf", data, params)
    assert ours["x"].iloc[-1] == forward["x"].iloc[-1]          # the last state has no future to use
    assert np.all(ours["p_xx"].iloc[:-1].to_numpy() < forward["p_xx"].iloc[:-1].to_numpy())


def test_epoch_ukf_equals_filterpys_ukf_on_the_same_measurements():
    params = {"accel_sigma_mps2": 0.4, "range_sigma_m": 0.2, "self_fit": "none"}
    data = noisy_walk()
    p = registry.get("ukf").resolve(params)
    ours = registry.run("ukf", data, params)
    source = MeasurementSource(data, "toa", "all", 0.2, True, 100.0, None)
    grid = data.grid(0.5, True, 100.0)
    F, Q = constant_velocity(0.5, 0.4)
    points = MerweScaledSigmaPoints(4, alpha=p["alpha"], beta=p["beta"], kappa=p["kappa"])
    ref = FilterpyUKF(dim_x=4, dim_z=4, dt=0.5, hx=None, fx=lambda x, dt: F @ x, points=points)
    ref.x = np.array([ours["x"].iloc[0], ours["y"].iloc[0], 0.0, 0.0])
    ref.P = np.diag([p["initial_sigma_m"] ** 2] * 2 + [p["initial_speed_sigma_mps"] ** 2] * 2)
    ref.Q = Q
    start = int(np.searchsorted(grid, ours["t"].iloc[0]))
    for k, model in enumerate(source.epoch_models(grid, 0.5)[start + 1:], start=1):
        ref.predict()
        ref.update(model.z, R=model.R(), hx=model.h)
        assert ours["x"].iloc[k] == pytest.approx(ref.x[0], abs=1e-9)
        assert ours["y"].iloc[k] == pytest.approx(ref.x[1], abs=1e-9)
        assert ours["p_xx"].iloc[k] == pytest.approx(ref.P[0, 0], abs=1e-9)


def test_sequential_smoother_equals_epoch_smoother_when_measurements_share_the_epoch_time():
    """All ranges of an epoch at t_k: both forward passes update at t_k, so the recorded
    chains and their smoothed states are the same."""
    data, _ = epoch_stamped_bursts(120)
    epoch = registry.run("ekf_rts", data, {"update": "epoch"})
    sequential = registry.run("ekf_rts", data, {"update": "sequential"})
    assert len(epoch) == len(sequential) > 100
    np.testing.assert_allclose(sequential[["t", "x", "y", "p_xx", "p_yy"]].to_numpy(),
                               epoch[["t", "x", "y", "p_xx", "p_yy"]].to_numpy(), rtol=0, atol=1e-9)


def test_smoother_restarts_with_the_track_after_the_coasting_limit():
    times, ids = bursts(100.0, 0.5, SQUARE)
    keep = (times < 30.0) | (times > 60.0)
    data = run_data(tables_for(times[keep], ids[keep], walk, SQUARE, noise_m=0.1, rng=np.random.default_rng(4)))
    forward = registry.run("ekf", data, {"max_coast_s": 5.0})
    smoothed = registry.run("ekf_rts", data, {"max_coast_s": 5.0})
    assert smoothed.attrs["resets"] == forward.attrs["resets"] == 1
    np.testing.assert_array_equal(smoothed["t"], forward["t"])
    last_before_gap = int(np.flatnonzero(forward["t"].to_numpy() < 45.0)[-1])
    # each segment ends on its own filtered state: nothing from after the gap flows back
    assert smoothed["x"].iloc[last_before_gap] == forward["x"].iloc[last_before_gap]


def test_particle_filter_is_reproducible_for_a_seed_and_run_and_varies_otherwise():
    data = noisy_walk(seconds=20.0)
    a = registry.run("pf", data, {"seed": 1, "n_particles": 300})
    b = registry.run("pf", noisy_walk(seconds=20.0), {"seed": 1, "n_particles": 300})
    pd.testing.assert_frame_equal(a, b)
    other_seed = registry.run("pf", data, {"seed": 2, "n_particles": 300})
    renamed = noisy_walk(seconds=20.0)
    renamed.name = "another run"                      # the stream follows the measurements, not the name
    pd.testing.assert_frame_equal(a, registry.run("pf", renamed, {"seed": 1, "n_particles": 300}))
    other_run = registry.run("pf", noisy_walk(seed=9, seconds=20.0), {"seed": 1, "n_particles": 300})
    assert not np.allclose(a["x"], other_seed["x"]) and not np.allclose(a["x"], other_run["x"])


def test_robust_estimators_bound_the_influence_of_outlier_ranges():
    """5% of the ranges 8 m too long (NLOS-like): the robust sliding window and the particle
    filter with the outlier mixture keep their 95th-percentile error near the range noise; the
    Gaussian EKF without its gate and the least-squares window follow the outliers by metres."""
    rng = np.random.default_rng(9)
    times, ids = bursts(120.0, 0.5, SQUARE)
    tables = tables_for(times, ids, walk, SQUARE, noise_m=0.1, rng=rng)
    outliers = rng.random(len(times)) < 0.05
    tables["ranges"].loc[outliers, "range_m"] += 8.0
    data = run_data(tables)
    p95 = {}
    for cell, name, params in [("ekf", "ekf", {"update": "sequential", "range_sigma_m": 0.1, "gate_probability": 0.0}),
                               ("window", "sliding_window", {"range_sigma_m": 0.1}),
                               ("window_l2", "sliding_window", {"range_sigma_m": 0.1, "loss": "linear"}),
                               ("pf", "pf", {"update": "sequential", "range_sigma_m": 0.1,
                                             "outlier_probability": 0.05, "outlier_span_m": 30.0})]:
        error = score(registry.run(name, data, params), data.table("truth"))["error_m"].iloc[10:]
        p95[cell] = np.nanpercentile(error, 95)
    assert p95["window"] < 0.6 and p95["pf"] < 0.6
    assert p95["ekf"] > 2.0 and p95["window_l2"] > 2.0


def test_study_cells_report_their_time_per_output_step():
    runs = {"run-01": noisy_walk(seconds=10.0).tables}
    p = registry.get("ekf").resolve({})
    _, metrics = run_cell("synthetic/walk", "ekf", "ekf", p, ["all"], runs, None)
    assert metrics["time_per_step"].iloc[0] > 0


@pytest.mark.parametrize("name", NEW)
def test_new_estimators_are_listed_with_documented_parameters(name):
    description = registry.get(name).describe()
    assert description["summary"] and all(p["doc"] for p in description["parameters"])


def test_pva_smoother_on_a_simulated_run_improves_on_the_forward_filter(simulated_run, tmp_path):
    """PVA (measured acceleration as input, bias states) through `wsnloc estimate` on a
    simulated Newcom++ run: the smoother's last estimate is the forward filter's (no future
    to use), and using the whole run lowers the RMS error. (The inputs' handling is
    checked against the batch solution in the next test; here they are small: ~1 cm per step.)
    Epoch updates: in sequential mode the recorded forward pass splits its predictions at the
    output times (smoothing.py), so its last estimate differs from the plain filter's by round-off
    of Q(a) + Q(b) against Q(a + b). No gate and no self-fit: ekf_pva (paper C's) has neither, ekf_rts
    has both by default."""
    metrics = {}
    for estimator in ("ekf_pva", "ekf_rts"):
        out = tmp_path / estimator
        assert main(["estimate", "--format", "newcom", str(simulated_run), "--out", str(out), "--estimator",
                     estimator, "--set", "motion=pva", "--set", "update=epoch", "--set", "gate_probability=0",
                     "--set", "self_fit=none"]) == 0
        metrics[estimator] = (json.loads((out / "metrics.json").read_text()), pd.read_parquet(out / "estimates.parquet"))
    (forward, forward_estimates), (smoothed, smoothed_estimates) = metrics["ekf_pva"], metrics["ekf_rts"]
    assert len(smoothed_estimates) == len(forward_estimates) > 100
    assert smoothed_estimates["x"].iloc[-1] == pytest.approx(forward_estimates["x"].iloc[-1], abs=1e-12)
    assert smoothed["rmse_m"] < forward["rmse_m"] < 2.0      # RTS minimises the mean square error


def _batch_smoothed(x0, P0, F, Q, H, R, zs, inputs, B):
    """Whole-segment least squares: prior on x_0, measurements z_k (k >= 1) and dynamics with
    the input B u_k where given; its minimiser is the smoothed trajectory."""
    n, N = len(x0), len(zs) + 1
    Wp, Wq, Wr = (np.linalg.inv(np.linalg.cholesky(c)) for c in (P0, Q, R))
    rows, rhs = [_block_row([(0, Wp)], N, n)], [Wp @ x0]
    for k in range(1, N):
        rows += [_block_row([(k, Wr @ H)], N, n), _block_row([(k, Wq), (k - 1, -Wq @ F)], N, n)]
        rhs += [Wr @ zs[k - 1], Wq @ (B @ inputs[k - 1] if inputs[k - 1] is not None else np.zeros(n))]
    return np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0].reshape(N, n)


def test_forward_pass_smooths_each_track_segment_like_the_batch_solution_with_mixed_inputs():
    """Two track segments (a reset between them), PVA steps with an input on every other step,
    an output repeated on one node: each output is the batch solution of its own segment."""
    rng = np.random.default_rng(6)
    F, B, Q = pva(0.5, 0.2, 0.05)
    Q = Q + np.eye(6) * 1e-4                                     # positive definite for the batch whitening
    H, R = np.hstack([np.eye(2), np.zeros((2, 4))]), np.eye(2) * 0.3
    forward, expected = ForwardPass(), []
    for length in (12, 9):
        x0, P0 = rng.normal(0, 1, 6), np.eye(6)
        kf = KalmanFilter(x0, P0, F, Q, H, R)
        forward.start(kf)
        forward.output()
        zs = rng.normal(0, 1, (length, 2)) + np.arange(length)[:, None] * 0.4
        inputs = [rng.normal(0, 2.0, 2) if k % 2 else None for k in range(length)]
        for z, u in zip(zs, inputs):
            kf.predict(F, Q, u=u, B=None if u is None else B)
            kf.update(z)
            forward.node(kf, (F, Q, None if u is None else B, u))
            forward.output()
        forward.output()                                          # the last node output twice
        batch = _batch_smoothed(x0, P0, F, Q, H, R, zs, inputs, B)
        expected += list(batch) + [batch[-1]]
    smoothed = np.array([x for x, _ in forward.smooth()])
    np.testing.assert_allclose(smoothed, np.array(expected), rtol=0, atol=1e-9)
