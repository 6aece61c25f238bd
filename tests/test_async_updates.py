"""Every registry filter, smoother and the sliding window on asynchronous data: the update mode
chosen from the data (estimators.auto), the sequential path checked in closed form and against
filterpy, the numerical guards (filters.numerics) and the particle filter's restart from a fix."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter as FilterpyEKF
from synthetic import SQUARE, bursts, one_at_a_time, run_data, tables_for, walk

from wsnloc.diagnosis import diagnose_run, report
from wsnloc.estimators import bayes, registry
from wsnloc.estimators.auto import update_mode
from wsnloc.estimators.filter_options import UpdateCounts, configured_factory
from wsnloc.filters.kalman import ExtendedKalmanFilter, KalmanFilter
from wsnloc.filters.measurement_models import RangeModel, Stacked
from wsnloc.filters.numerics import Guards, regularise, safe_cholesky
from wsnloc.filters.particle import ParticleFilter
from wsnloc.filters.sliding_window import SlidingWindowEstimator
from wsnloc.filters.ukf import UnscentedKalmanFilter
from wsnloc.metrics.tracking import run_metrics, score

# ekf_p (paper C's P model: a random walk without velocity) is not among them: on a walk ranged
# one anchor at a time it lags by construction (2.3x tracker's median at best over p_sigma_m
# 0.5-4 m and range_sigma_m 0.1-0.3 m on benchmarks/async_estimators.py's 600 s walk)
FILTERS_AND_SMOOTHERS = ("ekf", "ukf", "pf", "ekf_filterpy", "ekf_rts", "ukf_rts", "sliding_window")


@pytest.fixture(scope="module")
def one_by_one():
    """A 1 m/s walk ranged one random anchor at a time (Poisson, 4 Hz, 0.1 m noise), 300 s."""
    rng = np.random.default_rng(21)
    times, ids = one_at_a_time(300.0, 4.0, rng, SQUARE)
    return tables_for(times, ids, lambda t: walk(t, 1.0), SQUARE, noise_m=0.1, rng=rng)


def _range(anchor_xy, z, sigma=0.3) -> Stacked:
    """A model of one range z (m) to the anchor at anchor_xy (m)."""
    return Stacked([RangeModel(np.array([anchor_xy], dtype=float), np.array([sigma]))], np.array([z], dtype=float))


def _metrics(name, tables, overrides=None):
    estimates = registry.run(name, run_data(tables), overrides or {})
    return estimates, run_metrics(score(estimates, tables["truth"]), tables["truth"])


# ---- the mode chosen from the data -------------------------------------------------------------
def test_auto_update_is_sequential_one_anchor_at_a_time_and_epoch_on_synchronous_rounds(one_by_one):
    rng = np.random.default_rng(2)
    grid = np.arange(1, 201) * 0.5
    times, ids = one_by_one["ranges"]["t"].to_numpy(), one_by_one["ranges"]["anchor_id"].to_numpy()
    assert update_mode(times, ids, grid, 0.5)[0] == "sequential"
    t_burst, id_burst = bursts(100.0, 0.5, SQUARE)
    assert update_mode(t_burst, id_burst, grid, 0.5)[0] == "epoch"
    # each anchor of a round at its own time stamp, 1 ms apart (a TDMA round): asynchronous
    staggered = t_burst - 0.001 * np.tile(np.arange(4), len(t_burst) // 4)
    assert update_mode(staggered, id_burst, grid, 0.5)[0] == "sequential"
    assert update_mode(np.sort(rng.uniform(0, 100, 10)), np.array(["A1"] * 10, dtype=object), grid, 0.5)[0] == \
        "sequential"


def test_filters_report_the_mode_auto_chose_and_keep_an_explicit_one(one_by_one):
    estimates = registry.run("ekf", run_data(one_by_one))
    assert estimates.attrs["update"] == "sequential"
    assert registry.run("ekf", run_data(one_by_one), {"update": "epoch"}).attrs["update"] == "epoch"
    t_burst, id_burst = bursts(60.0, 0.5, SQUARE)
    burst = tables_for(t_burst, id_burst, walk, SQUARE, noise_m=0.1, rng=np.random.default_rng(1))
    assert registry.run("ekf", run_data(burst)).attrs["update"] == "epoch"
    d = diagnose_run(run_data(one_by_one), estimates, registry.get("ekf").resolve({}))
    assert d["update"] == "sequential" and "sequential updates" in report(d, {})


def test_rss_alone_keeps_epoch_updates():
    """RSS samples of one receiver are averaged per epoch (correlated fading), whatever their times."""
    rng = np.random.default_rng(4)
    times, ids = one_at_a_time(60.0, 4.0, rng, SQUARE)
    tables = tables_for(times, ids, walk, SQUARE, noise_m=0.1, rng=rng, rss_times=np.arange(0.0, 60.0, 0.13))
    data = run_data(tables, {"p0_dbm": -40.0, "path_loss_exponent": 2.5, "sigma_db": 3.0, "d0_m": 1.0})
    p = registry.get("ekf").resolve({"measurements": "rss", "rss_calibration": "other_run"})
    assert bayes.resolve_update(data, p)["update"] == "epoch"
    assert bayes.resolve_update(data, dict(p, measurements="hybrid"))["update"] == "sequential"


# ---- acceptance on a synthetic one-anchor-at-a-time run ------------------------------------------
@pytest.mark.parametrize("name", FILTERS_AND_SMOOTHERS)
def test_every_filter_and_smoother_follows_ranges_one_anchor_at_a_time(one_by_one, name):
    """availability >= 0.9 and median within 1.5x of `tracker`'s (the issue's acceptance); in
    epoch mode the same filters lag up to one period behind the walk."""
    _, tracker = _metrics("tracker", one_by_one)
    estimates, ours = _metrics(name, one_by_one)
    assert ours["availability"] >= 0.9
    assert ours["median"] <= 1.5 * tracker["median"], (ours["median"], tracker["median"])


@pytest.fixture(scope="module")
def round_robin():
    """The 1 m/s walk ranged in strict turn, one anchor every 1/3 s: a 0.5 s period never holds
    three anchors, so an initiator window of one period never starts a track."""
    times = np.arange(1.0 / 3.0, 300.0, 1.0 / 3.0)
    ids = np.tile(np.array(list(SQUARE), dtype=object), len(times))[:len(times)]
    return tables_for(times, ids, lambda t: walk(t, 1.0), SQUARE, noise_m=0.1, rng=np.random.default_rng(2))


@pytest.mark.parametrize("name", FILTERS_AND_SMOOTHERS)
def test_every_filter_and_smoother_starts_on_ranges_in_strict_turn(round_robin, name):
    """The filters' default initiator window (one period, widened up to the tracker's 4 s while
    it holds no fix) starts them: availability >= 0.9, median within 1.5x of `tracker`'s; a fixed
    window of one period gives no estimate at all."""
    _, tracker = _metrics("tracker", round_robin)
    _, ours = _metrics(name, round_robin)
    assert ours["availability"] >= 0.9 and ours["median"] <= 1.5 * tracker["median"]
    if name != "sliding_window":                   # its own initiator: a window's ranges
        assert len(registry.run(name, run_data(round_robin), {"init_window_s": 0.5})) == 0


@pytest.fixture(scope="module")
def real_like_one_by_one():
    """The one-anchor-at-a-time walk (300 s) with the range errors of real outdoor UWB: a common
    7% scale error and per-anchor offsets up to 0.3 m."""
    rng = np.random.default_rng(22)
    times, ids = one_at_a_time(300.0, 4.0, rng, SQUARE)
    tables = tables_for(times, ids, lambda t: walk(t, 1.0), SQUARE, noise_m=0.1, rng=rng)
    offsets = tables["ranges"]["anchor_id"].map({"A1": 0.3, "A2": -0.2, "A3": 0.1, "A4": -0.3})
    tables["ranges"]["range_m"] = 1.07 * tables["ranges"]["range_m"] + offsets
    return tables


SELF_FITTED_BY_DEFAULT = ("ekf", "ukf", "pf", "ekf_filterpy", "ekf_rts", "ukf_rts")


@pytest.mark.parametrize("name", SELF_FITTED_BY_DEFAULT)
def test_filters_and_smoothers_self_fit_real_range_errors_like_the_tracker(real_like_one_by_one, name):
    """With a range scale error and per-anchor offsets the Bayesian filters and smoothers stay
    within 1.5x of `tracker`'s median by default (the tracker's self-fit, estimators.self_fit);
    the same estimator with the configured values (self_fit: none) is beyond 1.5x."""
    _, tracker = _metrics("tracker", real_like_one_by_one)
    estimates, ours = _metrics(name, real_like_one_by_one)
    _, plain = _metrics(name, real_like_one_by_one, {"self_fit": "none"})
    assert ours["availability"] >= 0.9
    assert ours["median"] <= 1.5 * tracker["median"], (ours["median"], tracker["median"])
    assert plain["median"] > 1.5 * tracker["median"], (plain["median"], tracker["median"])
    assert estimates.attrs["self_fit_range_correction"] == "applied"


def test_the_random_walk_preset_is_available_one_anchor_at_a_time(one_by_one):
    assert _metrics("ekf_p", one_by_one)[1]["availability"] >= 0.9


def test_epoch_updates_lag_on_the_same_run(one_by_one):
    """The comparison that can fail: forcing the old default (epoch) is clearly worse."""
    _, sequential = _metrics("ekf", one_by_one)
    _, epoch = _metrics("ekf", one_by_one, {"update": "epoch"})
    assert epoch["median"] > 1.5 * sequential["median"]


GATED_BY_DEFAULT = ("ekf", "ukf", "ekf_filterpy", "ekf_rts", "ukf_rts")


@pytest.fixture(scope="module")
def nlos_one_by_one():
    """The one-anchor-at-a-time walk (200 s) with 10% of its ranges NLOS: 2-6 m of excess path."""
    rng = np.random.default_rng(33)
    times, ids = one_at_a_time(200.0, 4.0, rng, SQUARE)
    tables = tables_for(times, ids, lambda t: walk(t, 1.0), SQUARE, noise_m=0.1, rng=rng)
    nlos = rng.random(len(tables["ranges"])) < 0.1
    tables["ranges"].loc[nlos, "range_m"] += rng.uniform(2.0, 6.0, nlos.sum())
    return tables


@pytest.mark.parametrize("name", GATED_BY_DEFAULT)
def test_general_filters_gate_nlos_ranges_by_default(nlos_one_by_one, name):
    """With NLOS outliers the general filters and smoothers stay within 1.5x of `tracker`'s
    median by default (the gate, 0.999); the same estimator without the gate (the papers'
    plain filter) is beyond 1.5x."""
    _, tracker = _metrics("tracker", nlos_one_by_one)
    estimates, gated = _metrics(name, nlos_one_by_one)
    _, ungated = _metrics(name, nlos_one_by_one, {"gate_probability": 0.0, "self_fit": "none"})
    assert registry.get(name).resolve({})["gate_probability"] == 0.999
    assert gated["median"] <= 1.5 * tracker["median"], (gated["median"], tracker["median"])
    assert ungated["median"] > 1.5 * tracker["median"], (ungated["median"], tracker["median"])
    assert 0.05 < estimates.attrs["gated_share"] < 0.2


def test_ukf_regression_update_equals_the_unscented_update_and_takes_the_gate():
    """linearise + update (H = Pxz^T P^-1, R + Omega) is the unscented update to round-off, and
    the gate of the EKF's updater rejects a 10-sigma range through it, keeping the others."""
    anchors = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]])
    x0, P0 = np.array([8.0, 9.0, 0.5, 0.0]), np.diag([0.3, 0.2, 0.25, 0.25])
    model = RangeModel(anchors, np.full(4, 0.2))
    true = np.array([8.2, 8.9])
    z = np.hypot(*(true - anchors).T)
    ukf = UnscentedKalmanFilter(x0, P0)
    ukf.update_model(Stacked([model], z))
    # the textbook unscented update, written out
    reference = UnscentedKalmanFilter(x0, P0)
    chi = reference.sigma_points()
    Z = np.array([model.h(c) for c in chi])
    z_hat = reference.Wm @ Z
    S = (reference.Wc[:, None] * (Z - z_hat)).T @ (Z - z_hat) + model.R()
    K = (reference.Wc[:, None] * (chi - x0)).T @ (Z - z_hat) @ np.linalg.inv(S)
    np.testing.assert_allclose(ukf.x, x0 + K @ (z - z_hat), atol=1e-12)
    np.testing.assert_allclose(ukf.P, P0 - K @ S @ K.T, atol=1e-12)
    z_wild = z.copy()
    z_wild[2] += 10.0 * np.sqrt(S[2, 2])
    p = registry.get("ukf").resolve({})
    counts = UpdateCounts()
    make = configured_factory(lambda x, P, motion: UnscentedKalmanFilter(x, P), p, counts)
    gated = make(x0, P0, None)
    gated.update_model(Stacked([model], z_wild))
    assert counts.offered == 4 and counts.gated == 1
    kept = UnscentedKalmanFilter(x0, P0)
    k = np.array([0, 1, 3])
    kept.update_model(Stacked([RangeModel(anchors[k], np.full(3, 0.2))], z[k]))
    np.testing.assert_allclose(gated.x, kept.x, atol=1e-12)


# ---- the sequential path, independently --------------------------------------------------------
def test_sequential_update_of_independent_measurements_equals_the_joint_update():
    """Linear KF: two measurements with independent noise, one after the other (no predict
    between), give exactly the joint (stacked) update's mean and covariance."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(4, 4))
    P0, x0 = A @ A.T + np.eye(4), rng.normal(size=4)
    H1, H2 = rng.normal(size=(1, 4)), rng.normal(size=(1, 4))
    R1, R2, z1, z2 = np.array([[0.3]]), np.array([[0.7]]), np.array([1.2]), np.array([-0.4])
    joint = KalmanFilter(x0, P0, np.eye(4), np.zeros((4, 4)), np.vstack([H1, H2]), np.diag([0.3, 0.7]))
    joint.update(np.r_[z1, z2])
    seq = KalmanFilter(x0, P0, np.eye(4), np.zeros((4, 4)), H1, R1)
    seq.update(z1)
    seq.update(z2, H2, R2)
    np.testing.assert_allclose(seq.x, joint.x, atol=1e-12)
    np.testing.assert_allclose(seq.P, joint.P, atol=1e-12)


def test_sequential_ekf_equals_filterpy_predicting_to_each_range(one_by_one):
    """The registry's ekf on ranges one anchor at a time (auto: sequential) against filterpy's
    EKF stepped by hand: predict over each range's own dt, update with it, and the output at
    each epoch end predicted from the last update."""
    data = run_data(one_by_one)
    p = registry.get("ekf").resolve({"self_fit": "none"})
    ours = registry.run("ekf", data, {"self_fit": "none"})
    source, motion = bayes.measurement_source(data, p), bayes.motion_model(p)
    records, times = source.records(), data.grid(p["epoch_s"], True, p["max_range_m"])
    initiator = bayes.components(p)[0]              # one period, widened while it holds no fix
    start = next(i for i, t in enumerate(records.t) if initiator.initiate(source, t, motion) is not None)
    x0, P0 = initiator.initiate(source, records.t[start], motion)
    ref = FilterpyEKF(dim_x=4, dim_z=1)
    ref.x, ref.P, t_ref = x0.copy(), P0.copy(), records.t[start]
    outputs, j = [], start + 1
    for t_k in times[times >= records.t[start]]:
        while j < len(records.t) and records.t[j] <= t_k:
            ref.F, ref.Q, _ = motion.matrices(records.t[j] - t_ref)
            ref.predict()
            model = _range(data.positions([records.anchor[j]])[0], records.value[j], p["range_sigma_m"])
            ref.update(model.z, HJacobian=model.jacobian, Hx=model.h, R=model.R())
            t_ref, j = records.t[j], j + 1
        F, _, _ = motion.matrices(t_k - t_ref)
        outputs.append((t_k, *(F @ ref.x)[:2]))
    outputs = np.array(outputs)
    assert len(ours) == len(outputs)
    np.testing.assert_allclose(ours[["t", "x", "y"]].to_numpy(), outputs, atol=1e-8)


# ---- numerical guards ----------------------------------------------------------------------------
def test_an_indefinite_covariance_is_regularised_and_counted():
    A = np.array([[1.0, 2.0], [2.0, 1.0]])                      # eigenvalues 3, -1
    guards = Guards()
    L = safe_cholesky(A, guards)
    assert guards.regularised == 1 and np.all(np.linalg.eigvalsh(L @ L.T) > 0)
    assert np.allclose(regularise(np.diag([2.0, 1.0])), np.diag([2.0, 1.0]))   # PD: unchanged
    ukf = UnscentedKalmanFilter(np.zeros(2), A, guards=guards)
    assert ukf.sigma_points().shape == (5, 2) and guards.regularised == 2


def test_an_update_with_a_non_finite_model_is_skipped_and_counted():
    guards = Guards()
    ekf = ExtendedKalmanFilter(np.array([1.0, 1.0, 0.0, 0.0]), np.eye(4), np.eye(4), np.zeros((4, 4)), guards)
    ekf.update_model(_range((0.0, 0.0), np.nan))
    assert guards.skipped == 1 and np.allclose(ekf.x, [1.0, 1.0, 0.0, 0.0])
    ukf = UnscentedKalmanFilter(np.array([1.0, 1.0]), np.eye(2), guards=guards)
    ukf.update_model(_range((0.0, 0.0), np.nan))
    assert guards.skipped == 2 and np.allclose(ukf.x, [1.0, 1.0])


def test_sliding_window_survives_a_singular_information_matrix():
    """Ranges from one anchor only leave the position along the circle unobservable: J^T J is
    singular. Regularised (counted), not 'Matrix is not positive definite'."""
    guards = Guards()
    solver = SlidingWindowEstimator(2.0, 0.5, 0.5, guards=guards)
    J = np.zeros((6, 4 * solver.n_knots))
    J[:, 0] = 1.0
    cov = solver._covariance(J)
    assert guards.regularised == 1 and np.all(np.isfinite(cov)) and np.all(np.linalg.eigvalsh(cov) > 0)


def test_sliding_window_on_one_anchor_for_a_while_does_not_crash():
    """After a start on four anchors only one anchor is heard for 20 s: the estimator keeps
    going (regularising what it must) for max_coast_s (10 s), is dropped (one anchor gives a
    distance, not a position: core.Support), restarts when the others are back and reports its
    counters."""
    rng = np.random.default_rng(8)
    times, ids = bursts(60.0, 0.25, SQUARE)
    lone = (times > 20.0) & (times < 40.0)
    keep = ~lone | (ids == "A1")
    tables = tables_for(times[keep] - rng.uniform(0, 0.2, keep.sum()), ids[keep], walk, SQUARE, noise_m=0.1, rng=rng)
    estimates = registry.run("sliding_window", run_data(tables))
    assert len(estimates) > 90 and {"regularised", "skipped", "withheld"} <= set(estimates.attrs)
    assert estimates.attrs["resets"] >= 1 and not estimates["t"].between(31.0, 40.0).any()
    assert estimates["t"].max() > 59.0


# ---- the particle filter starts from a fix and survives a bad one -------------------------------
def test_particle_filter_restarts_from_a_fix_when_its_likelihood_collapses():
    """The first 1.5 s of ranges are 8 m too long (a bad first fix far from the target, with
    P0's 1 m spread around it). The collapse of the cloud's likelihood restarts it from a fresh
    fix (counted) within seconds; without the restart the cloud was still metres off 5-10 s in
    (4.7, 7.1 and 4.8 m mean error on seeds 3-5, against 0.1 m). Over 8 streams (`seed` 0-7): in
    one (measured 2026-12-07) the restarted cloud took the mirror image of the target across the
    line of two anchors, which explains half of the ranges that come one anchor at a time, so a
    majority of misses never came until the walk left it (10 s): at least 7 of 8 recover."""
    rng = np.random.default_rng(3)
    times, ids = one_at_a_time(60.0, 8.0, rng, SQUARE)
    tables = tables_for(times, ids, lambda t: walk(t, 1.0), SQUARE, noise_m=0.1, rng=rng)
    bad = tables["ranges"]["t"] < 1.5
    tables["ranges"].loc[bad, "range_m"] += 8.0
    recovered = 0
    for seed in range(8):
        estimates = registry.run("pf", run_data(tables), {"init_window_s": 1.5, "seed": seed})
        scored = score(estimates, tables["truth"])
        assert estimates.attrs["reinitialised"] >= 1 and estimates.attrs["resets"] >= 1
        soon = scored[(scored["t"] > 5.0) & (scored["t"] <= 10.0)]
        recovered += np.nanmean(soon["error_m"]) < 0.5
    assert recovered >= 7


def test_particle_filter_collapse_needs_most_of_the_recent_updates_to_miss():
    """One wild range (an outlier) does not restart the filter; a run of them does."""
    pf = ParticleFilter(np.array([10.0, 10.0, 0.0, 0.0]), np.diag([0.1, 0.1, 0.01, 0.01]), 500,
                        np.random.default_rng(0))
    good = np.hypot(10.0, 10.0)
    for z in [good] * 5 + [good + 20.0] + [good] * 5:
        pf.update_model(_range((0.0, 0.0), z, 0.1))
    assert not pf.lost
    for _ in range(6):
        pf.update_model(_range((0.0, 0.0), good + 20.0, 0.1))
    assert pf.lost and pf.guards.reinitialised == 1


# ---- per-epoch solvers and trackers over fixes ------------------------------------------------------
@pytest.mark.parametrize("name", ["minmax", "multilateration", "pmix", "fmix", "velocity_tracker", "kf_tracker"])
def test_per_epoch_solvers_fix_ranges_one_anchor_at_a_time(one_by_one, name):
    """Most 0.5 s epochs hear one or two anchors: the fixes read each anchor's latest range of
    the last 4 s (auto.fix_window_epochs); one epoch alone gave a fix in 17% of the time."""
    assert _metrics(name, one_by_one)[1]["availability"] >= 0.9


def test_fix_window_stays_one_epoch_on_synchronous_rounds():
    from wsnloc.estimators.auto import fix_window_epochs
    assert fix_window_epochs(np.array([4, 4, 0, 3, 2]), 0.5) == 1
    assert fix_window_epochs(np.array([1, 2, 0, 1, 3]), 0.5) == 8


def test_particle_filter_stream_follows_the_measurements_not_the_run_name(one_by_one):
    """The same measurements under two names (two folders), or in another row order in the file
    (line numbers; rows of one time stamp swapped), give the same stream and estimates; a run with
    one range changed draws another stream."""
    from synthetic import run_data as named
    a = registry.run("pf", named(one_by_one, name="alpha/run-01"), {"self_fit": "none"})
    b = registry.run("pf", named(one_by_one, name="beta/run-01"), {"self_fit": "none"})
    np.testing.assert_array_equal(a[["x", "y"]].to_numpy(), b[["x", "y"]].to_numpy())
    lines = one_by_one["ranges"]["line"].to_numpy()[::-1]            # the file's rows in another order
    reordered = registry.run("pf", named(dict(one_by_one, ranges=one_by_one["ranges"].assign(line=lines))),
                             {"self_fit": "none"})
    np.testing.assert_array_equal(a[["x", "y"]].to_numpy(), reordered[["x", "y"]].to_numpy())
    changed = dict(one_by_one, ranges=one_by_one["ranges"].assign(
        range_m=one_by_one["ranges"]["range_m"] + np.r_[1e-3, np.zeros(len(one_by_one["ranges"]) - 1)]))
    draw = [bayes.run_generator(0, named(tables, name="alpha/run-01")).random(4) for tables in (one_by_one, changed)]
    assert not np.array_equal(*draw)
    t_burst, id_burst = bursts(20.0, 0.5, SQUARE)                    # four ranges per time stamp
    burst = tables_for(t_burst, id_burst, walk, SQUARE, noise_m=0.1, rng=np.random.default_rng(1))
    swapped = dict(burst, ranges=burst["ranges"].sort_values(["t", "anchor_id"], ascending=[True, False]))
    assert not burst["ranges"]["anchor_id"].equals(swapped["ranges"]["anchor_id"].reset_index(drop=True))
    draw = [bayes.run_generator(0, named(tables)).random(4) for tables in (burst, swapped)]
    np.testing.assert_array_equal(*draw)                         # rows of one time stamp in another order


def test_no_estimate_from_the_sliding_window_names_the_window_too_short_for_a_start():
    """Ranged in strict turn at 1.5 Hz, no 2 s window ending at an output time holds the 4 ranges
    its start needs: no estimate, and the reason says so with the setting that helps."""
    from wsnloc.studies import diagnose
    times = np.arange(1.0 / 1.5, 120.0, 1.0 / 1.5)
    ids = np.tile(np.array(list(SQUARE), dtype=object), len(times))[:len(times)]
    data = run_data(tables_for(times, ids, walk, SQUARE, noise_m=0.1, rng=np.random.default_rng(1)))
    p = registry.get("sliding_window").resolve({})
    assert len(registry.run("sliding_window", data)) == 0
    assert "no window of window_s (2 s) holds the 4 ranges a start needs (at most 3" in diagnose(data, p)
    assert len(registry.run("sliding_window", data, {"window_s": 4.0})) > 100
    assert "window_s" not in diagnose(data, registry.get("ekf").resolve({}))
