"""The estimator registry: every estimator on noise-free geometry, the parameter contract,
sequential against epoch updates, asynchronous ranges, gaps and the coasting limit."""

import numpy as np
import pandas as pd
import pytest
from filterpy.kalman import ExtendedKalmanFilter as FilterpyEKF

from synthetic import RSS_MODEL, SQUARE, bursts, epoch_stamped_bursts, one_at_a_time, run_data, tables_for, walk
from wsnloc.errors import ConfigError
from wsnloc.estimators import registry
from wsnloc.estimators.measurements import MeasurementSource, RssParams
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.metrics.tracking import availability, run_metrics, score

CROSS = {"N": (10.0, 18.0), "S": (10.0, 2.0), "E": (18.0, 10.0), "W": (2.0, 10.0)}   # symmetric around (10, 10)
TARGET = np.array([10.0, 10.0])
CONFIGURED_RSS = {"rss_calibration": "configured", **{k: RSS_MODEL[k] for k in ("p0_dbm", "path_loss_exponent",
                                                                                 "sigma_db", "d0_m")}}


def static_run(anchors=CROSS, seconds=60.0, rss=False):
    times, ids = bursts(seconds, 0.5, anchors)
    tables = tables_for(times, ids, TARGET, anchors, rss_times=np.unique(times) if rss else None)
    return run_data(tables)


def test_registry_lists_at_least_twelve_estimators_with_documented_parameters():
    assert len(registry.ESTIMATORS) >= 12
    for estimator in registry.ESTIMATORS.values():
        description = estimator.describe()
        assert description["summary"] and description["parameters"]
        for p in description["parameters"]:
            assert p["doc"] and "unit" in p and "default" in p


def test_unknown_parameter_is_refused_naming_the_key():
    with pytest.raises(ConfigError, match=r"'studies.s.estimators.x.acel_sigma_mps2': unknown parameter"):
        registry.get("ekf").resolve({"acel_sigma_mps2": 1.0}, "studies.s.estimators.x")
    with pytest.raises(ConfigError, match=r"'estimator ekf.motion': 'pvx' is not one of p, pv, pva"):
        registry.get("ekf").resolve({"motion": "pvx"})
    with pytest.raises(ConfigError, match=r"unknown estimator 'ekff'"):
        registry.get("ekff")


@pytest.mark.parametrize("name, params", [
    ("minmax", {}), ("multilateration", {}), ("minmax", {"measurements": "rss", **CONFIGURED_RSS}),
    ("multilateration", {"measurements": "rss", **CONFIGURED_RSS}), ("pmix", CONFIGURED_RSS),
    ("fmix", CONFIGURED_RSS), ("fmix", {"solver": "multilateration", **CONFIGURED_RSS}),
])
def test_static_solvers_recover_the_position_exactly(name, params):
    """Noise-free ranges (and RSS by the configured model) to anchors in a cross around the
    target: Min-Max's box centre and multilateration are both exact there."""
    estimates = registry.run(name, static_run(rss=True), params)
    errors = np.hypot(estimates["x"] - TARGET[0], estimates["y"] - TARGET[1])
    assert len(estimates) >= 100 and errors.max() < 1e-6


@pytest.mark.parametrize("name, params", [
    ("velocity_tracker", {}), ("kf_tracker", {}), ("ekf", {}), ("ekf_p", {}), ("tracker", {}),
    ("ekf", {"measurements": "hybrid", **CONFIGURED_RSS}), ("ekf", {"measurements": "rss", **CONFIGURED_RSS}),
    ("ekf", {"update": "sequential"}),
])
def test_trackers_and_filters_converge_to_a_static_target(name, params):
    estimates = registry.run(name, static_run(seconds=120.0, rss=True), params)
    final = estimates[["x", "y"]].to_numpy()[-1]
    assert np.hypot(*(final - TARGET)) < 1e-3


def test_filters_report_their_position_covariance_and_trackers_over_fixes_do_not_invent_one():
    ekf = registry.run("ekf", static_run())
    assert np.all(ekf["p_xx"].iloc[1:] > 0) and np.all(np.isfinite(ekf["nis"].iloc[1:]))
    vt = registry.run("velocity_tracker", static_run())
    assert vt["p_xx"].isna().all()


def test_pv_ekf_follows_a_walk_with_noise_free_ranges():
    """Sequential updates predict to the output time: no lag behind the walk (the epoch mode
    outputs at the epoch's end what it measured up to a period earlier)."""
    times, ids = bursts(200.0, 0.5, SQUARE)
    data = run_data(tables_for(times, ids, walk, SQUARE))
    scored = score(registry.run("ekf", data, {"update": "sequential"}), data.table("truth"))
    assert np.nanmedian(scored["error_m"].iloc[20:]) < 0.02     # corners of the walk cost a few cm
    lagging = score(registry.run("ekf", data, {"update": "epoch"}), data.table("truth"))
    assert np.nanmedian(lagging["error_m"].iloc[20:]) == pytest.approx(0.25, abs=0.01)   # 0.5 m/s x 0.5 s


def test_sequential_equals_epoch_updates_when_measurements_share_the_epoch_time():
    """All ranges of an epoch carry the time t_k: predict to t_k then update in both modes."""
    data, ends = epoch_stamped_bursts(200)
    assert np.array_equal(data.grid(0.5, True, 100.0)[:len(ends)], ends)
    epoch = registry.run("ekf", data, {"update": "epoch", "epoch_s": 0.5})
    sequential = registry.run("ekf", data, {"update": "sequential", "epoch_s": 0.5})
    assert len(epoch) == len(sequential) > 150
    np.testing.assert_allclose(sequential[["t", "x", "y", "p_xx", "p_yy"]].to_numpy(),
                               epoch[["t", "x", "y", "p_xx", "p_yy"]].to_numpy(), rtol=0, atol=1e-9)


def test_epoch_ekf_equals_filterpy_on_the_same_measurements():
    """The registry's epoch EKF step by step against filterpy's ExtendedKalmanFilter."""
    rng = np.random.default_rng(8)
    times, ids = bursts(30.0, 0.5, SQUARE)
    data = run_data(tables_for(times, ids, walk, SQUARE, noise_m=0.2, rng=rng))
    ours = registry.run("ekf", data, {"accel_sigma_mps2": 0.4, "range_sigma_m": 0.2, "self_fit": "none"})
    params = registry.get("ekf").resolve({"accel_sigma_mps2": 0.4, "range_sigma_m": 0.2, "self_fit": "none"})
    source = MeasurementSource(data, "toa", "all", 0.2, True, 100.0, None)
    grid = data.grid(0.5, True, 100.0)
    models = source.epoch_models(grid, 0.5)
    F, Q = constant_velocity(0.5, 0.4)
    ref = FilterpyEKF(dim_x=4, dim_z=4)
    ref.x = np.array([ours["x"].iloc[0], ours["y"].iloc[0], 0.0, 0.0])
    ref.F, ref.Q = F, Q
    ref.P = np.diag([params["initial_sigma_m"] ** 2] * 2 + [params["initial_speed_sigma_mps"] ** 2] * 2)
    start = int(np.searchsorted(grid, ours["t"].iloc[0]))
    for k, model in enumerate(models[start + 1:], start=1):
        ref.predict()
        ref.update(model.z, HJacobian=model.jacobian, Hx=model.h, R=model.R())
        assert ours["x"].iloc[k] == pytest.approx(ref.x[0], abs=1e-9)
        assert ours["y"].iloc[k] == pytest.approx(ref.x[1], abs=1e-9)


def _async_and_burst_runs(seed=11, duration=1500.0, gap=(600.0, 660.0)):
    """The same walk ranged one anchor at a time (about 2 Hz, unsorted rows, a 60 s gap) and in
    bursts of all four anchors every 2 s (the same number of ranges)."""
    rng = np.random.default_rng(seed)
    times, ids = one_at_a_time(duration, 2.0, rng, SQUARE, gap)
    tables = tables_for(times, ids, walk, SQUARE, noise_m=0.1, rng=rng)
    shuffled = tables["ranges"].sample(frac=1.0, random_state=1).reset_index(drop=True)
    burst_times, burst_ids = bursts(duration, 2.0, SQUARE)
    burst_times = burst_times[(burst_times < gap[0]) | (burst_times > gap[1])]
    burst_ids = burst_ids[:len(burst_times)]
    burst = tables_for(burst_times, burst_ids, walk, SQUARE, noise_m=0.1, rng=rng)
    return dict(tables, ranges=shuffled), burst


def test_default_tracker_follows_ranges_that_arrive_one_anchor_at_a_time():
    one_by_one, burst = _async_and_burst_runs()
    tracked = score(registry.run(registry.DEFAULT_ESTIMATOR, run_data(one_by_one)), one_by_one["truth"])
    reference = score(registry.run(registry.DEFAULT_ESTIMATOR, run_data(burst)), burst["truth"])
    a = run_metrics(tracked, one_by_one["truth"])
    b = run_metrics(reference, burst["truth"])
    assert a["availability"] >= 0.95
    assert a["median"] <= 2.0 * b["median"]
    assert tracked.attrs["resets"] == 1                      # the 60 s gap exceeds the coasting limit


def test_window_initiator_starts_on_ranges_that_arrive_one_anchor_at_a_time():
    """At 1 Hz one anchor at a time an epoch of 0.5 s rarely holds 3 anchors; the tracker's
    initiator (multilateration over the last 4 s) starts within seconds, and so does a filter's
    default (init_window_s 0: one period, widened while it holds no fix), where a fixed window of
    one period starts later or never."""
    rng = np.random.default_rng(5)
    times, ids = one_at_a_time(300.0, 1.0, rng, SQUARE)
    data = run_data(tables_for(times, ids, walk, SQUARE, noise_m=0.1, rng=rng))
    started = registry.run("tracker", data)["t"].iloc[0]
    assert started < times[0] + 15.0
    assert registry.run("ekf", data, {"update": "sequential"})["t"].iloc[0] <= started
    single_epoch = registry.run("ekf", data, {"update": "sequential", "init_window_s": 0.5})
    assert len(single_epoch) == 0 or single_epoch["t"].iloc[0] > started


def test_no_measurements_for_longer_than_the_coasting_limit_drops_the_track():
    times, ids = bursts(100.0, 0.5, SQUARE)
    keep = (times < 30.0) | (times > 60.0)
    data = run_data(tables_for(times[keep], ids[keep], walk, SQUARE))
    estimates = registry.run("ekf", data, {"max_coast_s": 5.0})
    inside = estimates[(estimates["t"] > 35.5) & (estimates["t"] < 60.0)]
    assert len(inside) == 0 and estimates.attrs["resets"] == 1
    assert estimates["t"].max() > 99.0                       # restarted after the gap


def _one_anchor_stretch_run(alone=(60.0, 90.0), anchor="A3", seconds=150.0):
    """A walk ranged round-robin at 4 Hz (0.05 m noise), by `anchor` alone inside `alone`."""
    times = np.arange(0.25, seconds, 0.25)
    ids = np.tile(np.array(list(SQUARE), dtype=object), len(times))[:len(times)]
    inside = (times >= alone[0]) & (times < alone[1])
    ids[inside] = anchor
    return tables_for(times, ids, walk, SQUARE, noise_m=0.05, rng=np.random.default_rng(3))


@pytest.mark.parametrize("name", ["tracker", "ekf_rts", "pf"])
def test_one_anchor_alone_for_longer_than_the_coasting_limit_drops_the_track(name):
    """Ranged by one anchor alone for 30 s: a distance, not a position. A filter linearised at its
    moving estimate reads a bearing into those ranges and stayed confident while it drifted (this
    run: errors up to 8-18 m, 9-71 outputs beyond 3 position sigmas, before core.Support). Now the track
    is dropped max_coast_s into the stretch, restarted when the anchors are back (one reset), every
    output's error is within 3 position sigmas, and the diagnosis names the stretch."""
    from wsnloc.diagnosis import diagnose_run, findings
    tables = _one_anchor_stretch_run()
    data = run_data(tables)
    estimates = registry.run(name, data)
    coast = registry.get(name).resolve({})["max_coast_s"]
    assert estimates.attrs["resets"] == 1
    assert not estimates["t"].between(60.0 + coast + 0.5, 90.0).any()
    assert estimates["t"].max() > 149.0
    scored = score(estimates, tables["truth"]).dropna(subset=["error_m"])
    assert len(scored) > 200 and (scored["error_m"] <= 3.0 * np.sqrt(scored["p_xx"] + scored["p_yy"])).all()
    d = diagnose_run(data, estimates, dict(registry.get(name).resolve({}), update="sequential"))
    (start, end, alone), = d["gaps"]                 # s after the first range (0.25 s)
    assert (start, end, alone) == (pytest.approx(59.25, abs=0.3), pytest.approx(89.75, abs=0.3), "A3")
    assert "59-90 s (A3 alone)" in " ".join(findings(d, registry.get(name).resolve({})))


def test_one_anchor_stretches_are_named_for_the_sliding_window_and_within_the_estimators_subset():
    """The sliding window drops its solution on one anchor alone too, and the diagnosis says so;
    RSS of another receiver during the stretch does not hide it from a tracker that reads ranges."""
    from wsnloc.diagnosis import diagnose_run
    tables = _one_anchor_stretch_run()
    data = run_data(tables)
    window = registry.get("sliding_window").resolve({})
    assert [gap[2] for gap in diagnose_run(data, registry.run("sliding_window", data, window), window)["gaps"]] == ["A3"]
    rss = pd.DataFrame({"t": np.arange(60.0, 90.0, 0.5), "seq": -1, "anchor_id": "A1", "rss_dbm": -60.0, "line": 1})
    with_rss = run_data(dict(tables, rss=rss))
    tracker = registry.get("tracker").resolve({})
    estimates = registry.run("tracker", with_rss, tracker)
    assert [gap[2] for gap in diagnose_run(with_rss, estimates, tracker)["gaps"]] == ["A3"]


def test_support_is_the_last_use_of_an_anchor_other_than_the_latest():
    from wsnloc.estimators.core import Support
    support = Support(0.0)
    for t, anchor in [(1.0, "A"), (2.0, "A"), (3.0, "B"), (4.0, "B"), (5.0, "B")]:
        support.use([anchor], t)
    assert support.since == 2.0                     # B alone since A's last range at 2 s
    support.use(["C", "A"], 6.0)
    assert support.since == 6.0                     # two anchors in one update


def test_anchor_subsets_restrict_the_measurements():
    times, ids = bursts(20.0, 0.5, SQUARE)
    data = run_data(tables_for(times, ids, TARGET, SQUARE))
    data.campaign = type("C", (), {"spec": {"subsets": {"three": ["A1", "A2", "A3"]}}, "source": "test"})()
    source = MeasurementSource(data, "toa", "three", 0.3, True, 100.0, None)
    assert set(source.ranges["anchor_id"]) == {"A1", "A2", "A3"}
    with pytest.raises(ConfigError, match="anchor subset 'four'"):
        data.members("four")


def test_rss_model_from_the_donor_or_configured():
    data = static_run(rss=True)
    p = registry.get("ekf").resolve({"measurements": "rss", **CONFIGURED_RSS})
    from wsnloc.estimators.measurements import rss_params
    assert rss_params(data, p) == RssParams(-40.0, 2.5, 3.0, 1.0)
    data.rss_model = {"p0_dbm": -45.0, "path_loss_exponent": 3.0, "sigma_db": 4.0, "d0_m": 1.0}
    assert rss_params(data, dict(p, rss_calibration="other_run")).p0_dbm == -45.0
    assert rss_params(data, p).p0_dbm == -40.0


def test_availability_is_the_covered_share_of_the_truth_span():
    truth = pd.DataFrame({"t": [0.0, 10.0], "x": [0.0, 0.0], "y": [0.0, 0.0]})
    est = pd.DataFrame({"t": np.arange(1.0, 11.0), "x": 0.0, "y": 0.0})
    assert availability(est, truth) == pytest.approx(1.0)
    est.loc[est["t"] > 5, "x"] = np.nan
    assert availability(est, truth, period=1.0) == pytest.approx(0.5)


def test_motion_detection_skips_the_prediction_while_the_accelerometer_is_still():
    """A still IMU (gravity only) declares every epoch static: no process noise is added, so
    the covariance only shrinks with each update; without detection it settles at a floor."""
    data = static_run(seconds=30.0)
    t = np.arange(0.0, 31.0, 0.002)
    data.tables["imu"] = pd.DataFrame({"t": t, "ax": 0.0, "ay": 0.0, "az": 9.81, "gz": 0.0})
    detected = registry.run("ekf_motion_detection", data)
    plain = registry.run("ekf", data)
    assert np.all(np.diff(detected["p_xx"].to_numpy()) < 0)
    assert detected["p_xx"].iloc[-1] < 0.2 * plain["p_xx"].iloc[-1]


def _accelerating_line_run(seconds=40.0, accel=0.01):
    """A cart starting at rest at (2, 10) heading east with constant acceleration: a campaign
    path gives the start pose, the 5 Hz IMU is noise-free (constant input: dead reckoning is
    exact), ranges to the square's anchors are noise-free."""
    from wsnloc.campaign import Campaign

    def position(t):
        t = np.asarray(t, dtype=float)
        return np.column_stack([2.0 + 0.5 * accel * t**2, np.full(len(t), 10.0)])

    times, ids = bursts(seconds, 0.5, SQUARE)
    tables = tables_for(times, ids, position, SQUARE)
    t5 = np.arange(0.0, seconds + 0.2, 0.2)
    tables["imu_5hz"] = pd.DataFrame({"t": t5, "ax": accel, "ay": 0.0, "az": 9.81, "gz": 0.0, "in_gap": False})
    campaign = Campaign(name="line", format="generic", spec={"path": {"points": [[2.0, 10.0], [60.0, 10.0]]}})
    data = run_data(tables)
    data.campaign = campaign
    return data, position


def test_inertial_pipelines_on_a_noise_free_imu():
    data, position = _accelerating_line_run()
    dr = registry.run("dead_reckoning", data, {"static_start_s": 0.0})
    np.testing.assert_allclose(dr[["x", "y"]].to_numpy(), position(dr["t"]), atol=1e-9)
    for name in ("dr_sskf", "dr_kf"):   # fixes weigh little against an exact dead reckoning
        fused = registry.run(name, data, {"static_start_s": 0.0, "process_sigma_m": 1e-5, "fix_sigma_m": 1.0})
        assert np.abs(fused[["x", "y"]].to_numpy() - position(fused["t"])).max() < 0.01, name


def test_pva_filter_with_the_measured_acceleration_converges():
    data, position = _accelerating_line_run(60.0)
    pva = registry.run("ekf_pva", data, {"static_start_s": 0.0, "update": "sequential", "range_sigma_m": 0.05})
    final = pva[["x", "y"]].to_numpy()[-1]
    assert np.hypot(*(final - position([pva["t"].iloc[-1]])[0])) < 1e-3


def _frame_records(ranges: pd.DataFrame, rss: pd.DataFrame) -> tuple:
    """Records of a source's frames as built from the frames (anchor ids read per row)."""
    t = np.concatenate([ranges["t"].to_numpy(float), rss["t"].to_numpy(float)])
    order = np.argsort(t, kind="stable")
    anchor = np.concatenate([ranges["anchor_id"].to_numpy(object), rss["anchor_id"].to_numpy(object)])
    value = np.concatenate([ranges["range_m"].to_numpy(float), rss["rss_dbm"].to_numpy(float)])
    return t[order], np.r_[np.zeros(len(ranges)), np.ones(len(rss))][order], anchor[order], value[order]


@pytest.mark.parametrize("kinds", ["toa", "rss", "hybrid"])
def test_coded_sources_equal_their_frames_epochs_and_records(kinds):
    """A source's epochs and records (from the run's coded measurements, per-anchor means over
    all anchors selected per subset) equal build_epochs and records of its own frames, exactly;
    sources differing only in their noise share epochs, records and fixes, not models."""
    from wsnloc.estimators.epochs import build_epochs
    from wsnloc.estimators.range_calibration import RangeCorrection
    rng = np.random.default_rng(3)
    times = np.sort(rng.uniform(0.0, 30.0, 400))
    ids = rng.choice(list(SQUARE), len(times))
    data = run_data(tables_for(times, ids, walk, SQUARE, noise_m=0.2, rng=rng, rss_times=np.arange(0.1, 30.0, 0.3)))
    data.campaign = type("C", (), {"spec": {"subsets": {"three": ["A1", "A2", "A4"]}}, "source": "test"})()
    correction = RangeCorrection(1.01, 0.05, (("A2", 0.1),), "configured")
    rss = RssParams(-40.0, 2.5, 3.0, 1.0) if kinds != "toa" else None
    source = MeasurementSource(data, kinds, "three", 0.3, True, 100.0, rss, correction)
    assert set(source.ranges["anchor_id"]) <= {"A1", "A2", "A4"} and set(source.rss["anchor_id"]) <= {"A1", "A2", "A4"}
    assert (len(source.ranges) > 0) == (kinds != "rss") and (len(source.rss) > 0) == (kinds != "toa")
    grid = data.grid(0.5, True, 100.0)
    for got, want in zip(source.epochs(grid, 0.5), build_epochs(source.ranges, source.rss, 0.5, grid)):
        assert got.t == want.t
        for name in ("range_ids", "ranges", "rss_ids", "rss"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
    records = source.records()
    for got, want in zip((records.t, records.kind, records.anchor, records.value),
                         _frame_records(source.ranges, source.rss)):
        np.testing.assert_array_equal(got, want)
    noisier = MeasurementSource(data, kinds, "three", 0.6, True, 100.0, rss, correction)
    assert noisier.epochs(grid, 0.5) is source.epochs(grid, 0.5) and noisier.records() is source.records()
    fix = source.window_fix(grid[5], 1.0)
    assert fix is not None and noisier.window_fix(grid[5], 1.0) is fix
    assert noisier.epoch_models(grid, 0.5) is not source.epoch_models(grid, 0.5)
    # record-group models (GroupModels on a source with ranges: built when read) equal `model` of each
    # group's records exactly, with RSS in some groups (hybrid) too
    bounds, models = records.groups().tolist(), source.group_models
    assert len(models) == len(bounds) - 1
    x = np.array([7.0, 9.0, 0.5, -0.2])
    for model, a, b in zip(models, bounds[:-1], bounds[1:]):
        want = source.model(*records.split(a, b))
        np.testing.assert_array_equal(model.z, want.z)
        np.testing.assert_array_equal(model.R(), want.R())
        for got, expected in zip(model.linearise(x), want.linearise(x)):
            np.testing.assert_array_equal(got, expected)
    if kinds != "rss":          # the anchor coordinates are looked up once for sources differing in their noise
        assert noisier.group_models.anchors is models.anchors and noisier.group_models.sigma[0] == 0.6
