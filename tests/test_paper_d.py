"""Paper D building blocks against closed-form cases, and the KF against filterpy."""

import numpy as np
import pandas as pd
import pytest
from filterpy.kalman import KalmanFilter as FilterpyKF

from wsnloc import results
from wsnloc.experiments import paper_d
from wsnloc.estimators.epochs import build_epochs
from wsnloc.estimators.fixes import epoch_fixes
from wsnloc.estimators.run_data import RunData, preliminary_filter
from wsnloc.filters.kalman import KalmanFilter
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.geometry.lateration import min_max, multilateration
from wsnloc.geometry.selection import rss_to_distance, smallest_per_epoch
from synthetic import k_smallest
from wsnloc.estimators import core, registry
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker

RSS_MODEL = {"p0_dbm": -50.0, "path_loss_exponent": 3.0, "d0_m": 1.0}
SPEC = {   # experiments.paper_d as in config/config.yaml, RSS model configured
    "scenarios": ["newcom/constant"],
    "parameters": {"anchors": "UWB=12+ZigBee=21", "epoch_s": 0.5, "k_smallest": 6, "max_range_m": 50.0,
                   "rss_calibration": "configured", "p0_dbm": -50.0, "path_loss_exponent": 3.0},
    "estimators": {"velocity": {"estimator": "velocity_tracker"},
                   "kalman": {"estimator": "kf_tracker", "accel_sigma_mps2": 0.5, "position_sigma_m": 1.5,
                              "initial_speed_sigma_mps": 0.5}},
    "cost_iterations": 200,
}
LABEL = "newcom/constant"


def _ranges(anchors, target):
    return np.hypot(*(np.asarray(anchors, float) - target).T)


@pytest.mark.parametrize("target", [(3.0, 4.0), (12.3, 7.9), (0.5, 0.2)])
def test_multilateration_is_exact_on_noise_free_ranges(target):
    anchors = np.array([[0, 0], [10, 0], [0, 8], [10, 8], [5, 12]])
    for n in (3, 4, 5):
        assert multilateration(anchors[:n], _ranges(anchors[:n], target)) == pytest.approx(target, abs=1e-9)
        assert multilateration(anchors[:n], _ranges(anchors[:n], target), refine=False) == pytest.approx(target, abs=1e-9)


def test_min_max_is_exact_when_anchors_bound_the_target_on_both_axes():
    """Box edges touch the target when an anchor lies on each axis line through it."""
    target = np.array([3.0, 4.0])
    anchors = np.array([[0, 4], [7, 4], [3, 0], [3, 9]])
    assert min_max(anchors, _ranges(anchors, target)) == pytest.approx(target)
    assert min_max(anchors[:3], _ranges(anchors[:3], target))[0] == pytest.approx(3.0)


def test_min_max_box_centre_hand_computed():
    # Boxes: A (0,0) d=5 -> [-5,5]x[-5,5]; B (8,0) d=5 -> [3,13]x[-5,5]; C (4,6) d=3 -> [1,7]x[3,9]
    # Intersection [3,5] x [3,5], centre (4, 4).
    assert min_max([[0, 0], [8, 0], [4, 6]], [5, 5, 3]) == pytest.approx([4.0, 4.0])


@pytest.mark.parametrize("solve", [min_max, multilateration])
def test_no_fix_with_fewer_than_three_usable_ranges(solve):
    assert solve([[0, 0], [5, 0]], [1, 2]) is None
    assert solve([[0, 0], [5, 0], [0, 5]], [1, np.nan, 2]) is None
    assert solve(np.empty((0, 2)), []) is None


def test_multilateration_refuses_collinear_anchors():
    anchors = np.array([[0, 0], [5, 0], [10, 0]])
    assert multilateration(anchors, _ranges(anchors, (4.0, 3.0))) is None


def test_gauss_newton_improves_on_the_linear_solution():
    rng = np.random.default_rng(0)
    anchors = np.array([[0, 0], [10, 0], [0, 8], [10, 8], [5, 12], [2, 3]])
    target = np.array([4.0, 5.0])
    d = _ranges(anchors, target) + rng.normal(0, 0.3, len(anchors))

    def cost(p):
        return np.sum((_ranges(anchors, p) - d) ** 2)

    assert cost(multilateration(anchors, d)) <= cost(multilateration(anchors, d, refine=False))


def test_gauss_newton_reaches_the_least_squares_minimum_scipy_finds():
    """Noisy ranges from anchors around the target: our Gauss-Newton (Cramer's-rule steps)
    ends where scipy.optimize.least_squares (Levenberg-Marquardt) does."""
    from scipy.optimize import least_squares
    rng = np.random.default_rng(2013)
    anchors = np.array([[0, 0], [20, 0], [20, 12], [0, 12], [10, 6.5], [5, 11]], dtype=float)
    for _ in range(50):
        target = rng.uniform([2, 2], [18, 10])
        n = int(rng.integers(4, 7))
        d = _ranges(anchors[:n], target) + rng.normal(0, 0.1, n)
        reference = least_squares(lambda p, a=anchors[:n], d=d: _ranges(a, p) - d, target, method="lm",
                                  xtol=1e-15, ftol=1e-15, gtol=1e-15).x
        assert multilateration(anchors[:n], d) == pytest.approx(reference, abs=1e-6)


def test_k_smallest_pools_technologies():
    uwb = np.array([7.0, 1.5, 9.0, 4.0])
    narrowband = np.array([2.0, 12.0, 0.5, np.nan, 3.0])
    pooled = np.concatenate([narrowband, uwb])
    _, kept = smallest_per_epoch(np.zeros((1, 9, 2)), pooled[None], 4)
    assert kept[0].tolist() == [0.5, 1.5, 2.0, 3.0]      # both technologies, NaN never kept
    _, kept = smallest_per_epoch(np.zeros((1, 9, 2)), pooled[None], 20)
    assert np.isfinite(kept).sum() == 8


def _one_epoch(campaign, uwb_ids, uwb_r, nb_ids, rss):
    ranges = pd.DataFrame({"t": 1.0, "anchor_id": uwb_ids, "range_m": uwb_r, "status": 0, "line": 1})
    rss = pd.DataFrame({"t": 1.0, "seq": 0, "anchor_id": nb_ids, "rss_dbm": rss, "line": 1})
    return RunData({"ranges": ranges, "rss": rss, "anchors": campaign.anchors}, campaign)


def test_fmix_localises_the_six_smallest_pooled_ranges(campaign):
    target = np.array([10.0, 7.5])
    uwb_ids = np.array(["U01", "U02", "U03", "U04", "U05"], dtype=object)
    nb_ids = np.array(["Z03", "Z04", "Z05", "Z06"], dtype=object)
    data = _one_epoch(campaign, uwb_ids, np.zeros(5), nb_ids, np.zeros(4))
    uwb_r = _ranges(data.positions(uwb_ids), target)
    nb_r = _ranges(data.positions(nb_ids), target)
    data = _one_epoch(campaign, uwb_ids, uwb_r, nb_ids, -50.0 - 30.0 * np.log10(nb_r))   # exact inverse of the model
    params = registry.get("fmix").resolve(SPEC["parameters"])
    fix = {}
    for solver in ("multilateration", "minmax"):
        for technique in ("toa", "rss", "pmix", "fmix"):
            p = {**params, "solver": solver, "rss_calibration": "configured", "sigma_db": 4.0}
            fix[solver, technique] = epoch_fixes(data, p, technique)[["x", "y"]].to_numpy()[0]
    assert fix["multilateration", "fmix"] == pytest.approx(target, abs=1e-6)
    ids = np.concatenate([nb_ids, uwb_ids])
    pooled = np.concatenate([nb_r, uwb_r])
    keep = k_smallest(pooled, 6)
    assert min_max(data.positions(ids[keep]), pooled[keep]) == pytest.approx(fix["minmax", "fmix"])
    assert fix["minmax", "pmix"] == pytest.approx((fix["minmax", "toa"] + fix["minmax", "rss"]) / 2)


def test_rss_to_distance_inverts_the_path_loss_model():
    d = np.array([1.0, 3.0, 17.5])
    assert rss_to_distance(-45.0 - 27.0 * np.log10(d), -45.0, 2.7) == pytest.approx(d)


def test_preliminary_filter():
    ranges = pd.DataFrame({"t": [0, 1, 2, 3, 4], "anchor_id": ["U01"] * 5, "range_m": [3.0, 3.0, -1.0, 80.0, np.nan],
                           "status": [0, 7, 0, 0, 0], "line": [1, 2, 3, 4, 5]})
    assert preliminary_filter(ranges, 50.0)["line"].tolist() == [1]


class TestVelocityTracker:
    def _primed(self):
        tracker = VelocityBoundedTracker(window=2)
        tracker.step(0.0, (0.0, 0.0))
        tracker.step(1.0, (1.0, 0.0))            # window speed: 1 m/s
        return tracker

    def test_inside_the_bound_is_accepted(self):
        out = self._primed().step(2.0, (1.6, 0.5))   # 0.78 m from (1, 0), bound 1 m
        assert out == pytest.approx([1.6, 0.5])

    def test_outside_goes_on_the_circle_towards_the_raw_fix(self):
        out = self._primed().step(2.0, (4.0, 4.0))   # 5 m away along (3, 4)/5, bound 1 m
        assert out == pytest.approx([1.6, 0.8])

    def test_bound_scales_with_the_time_step(self):
        out = self._primed().step(3.0, (5.0, 0.0))   # 2 s at 1 m/s
        assert out == pytest.approx([3.0, 0.0])

    def test_stop_keeps_the_last_coordinates(self):
        tracker = self._primed()
        first = tracker.step(2.0, (4.0, 4.0)).copy()
        assert tracker.step(2.5, (4.0, 4.0)) == pytest.approx(first)

    def test_first_fixes_are_accepted(self):
        assert VelocityBoundedTracker().step(0.0, (5.0, 5.0)) == pytest.approx([5.0, 5.0])

    def test_speed_from_tracked_freezes_after_a_static_phase(self):
        """Why the default feeds raw fixes: with its own outputs the speed cannot recover."""
        frozen, live = VelocityBoundedTracker(3, "tracked"), VelocityBoundedTracker(3, "raw")
        for k in range(10):
            frozen.step(k * 0.5, (0.0, 0.0) if k % 2 == 0 else (0.0, 1e-12))
            live.step(k * 0.5, (0.0, 0.0) if k % 2 == 0 else (0.0, 1e-12))
        for k in range(10, 20):
            a, b = frozen.step(k * 0.5, (0.3 * (k - 9), 0.0)), live.step(k * 0.5, (0.3 * (k - 9), 0.0))
        assert a[0] < 1e-6 and b[0] > 1.0

    def test_window_must_be_positive(self):
        with pytest.raises(ValueError):
            VelocityBoundedTracker(0)


def test_kalman_filter_equals_filterpy():
    rng = np.random.default_rng(3)
    F, Q = constant_velocity(0.5, 0.4)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = np.eye(2) * 1.2
    x0, P0 = np.array([1.0, 2.0, 0.0, 0.0]), np.diag([2.0, 2.0, 0.3, 0.3])
    ours = KalmanFilter(x0, P0, F, Q, H, R)
    ref = FilterpyKF(dim_x=4, dim_z=2)
    ref.x, ref.P, ref.F, ref.Q, ref.H, ref.R = x0.copy(), P0.copy(), F, Q, H, R
    for k in range(200):
        ours.predict()
        ref.predict()
        if k % 7 != 3:                             # some epochs without a fix
            z = np.array([0.15 * k, 2.0]) + rng.normal(0, 1.0, 2)
            ours.update(z)
            ref.update(z)
        np.testing.assert_allclose(ours.x, ref.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours.P, ref.P, rtol=0, atol=1e-9)


def test_kf_tracker_equals_filterpy_over_the_runs_fixes(campaign, simulated_run):
    """kf_tracker (the core's epoch loop with the fix initiator and the array KF bank) against
    filterpy's KalmanFilter fed the same fixes: start at the first fix (x0 = [fix, 0, 0], P0),
    predict at every later epoch, update with each fix, output at the epochs with a fix."""
    from wsnloc.estimators import fixes
    from wsnloc.io.newcom import ingest_run

    tables, _ = ingest_run(simulated_run, campaign)
    data = RunData(tables, campaign)
    p = registry.get("kf_tracker").resolve({"anchors": "UWB=12", "k_smallest": 6, "max_range_m": 50.0})
    got = registry.run("kf_tracker", data, p)
    fix = fixes.epoch_fixes(data, p, p["fixes"])
    F, Q = constant_velocity(p["epoch_s"], p["accel_sigma_mps2"])
    ref, rows = None, []
    for t, x, y in fix[["t", "x", "y"]].itertuples(index=False):
        if ref is not None:
            ref.predict()
        if not (np.isfinite(x) and np.isfinite(y)):
            continue
        if ref is None:
            ref = FilterpyKF(dim_x=4, dim_z=2)
            ref.x = np.array([x, y, 0.0, 0.0])
            ref.P = np.diag([p["position_sigma_m"] ** 2] * 2 + [p["initial_speed_sigma_mps"] ** 2] * 2)
            ref.F, ref.Q, ref.H = F, Q, np.hstack([np.eye(2), np.zeros((2, 2))])
            ref.R = np.eye(2) * p["position_sigma_m"] ** 2
        else:
            ref.update(np.array([x, y]))
        rows.append((t, ref.x[0], ref.x[1], ref.P[0, 0], ref.P[0, 1], ref.P[1, 1]))
    expected = np.array(rows)
    assert len(expected) > 100 and got["n_meas"].iloc[0] == 0 and (got["n_meas"].iloc[1:] == 1).all()
    np.testing.assert_allclose(got[["t", "x", "y", "p_xx", "p_xy", "p_yy"]].to_numpy(), expected, rtol=0, atol=1e-9)


def test_constant_velocity_process_noise():
    F, Q = constant_velocity(2.0, 1.0)
    assert F[0, 2] == 2.0 and F[1, 3] == 2.0
    assert Q[0, 0] == pytest.approx(4.0) and Q[0, 2] == pytest.approx(4.0) and Q[2, 2] == pytest.approx(4.0)


def test_epochs_group_measurements():
    ranges = pd.DataFrame({"t": [0.1, 0.2, 0.7], "anchor_id": ["U01", "U01", "U02"], "range_m": [1.0, 3.0, 5.0],
                           "status": 0, "line": 1})
    rss = pd.DataFrame({"t": [0.05, 0.3, 0.6], "anchor_id": ["Z01", "Z01", "Z01"], "rss_dbm": [-60.0, -62.0, -70.0],
                        "seq": 0, "line": 1})
    epochs = build_epochs(ranges, rss, 0.5, times=np.array([0.5, 1.0]))
    assert [e.t for e in epochs] == [0.5, 1.0]
    assert epochs[0].range_ids.tolist() == ["U01"] and epochs[0].ranges.tolist() == [2.0]
    assert epochs[0].rss.tolist() == [-61.0] and epochs[1].rss.tolist() == [-70.0]


def test_epochs_equal_a_pandas_groupby_mean_per_epoch_and_anchor():
    """Unsorted times and ids, several samples per anchor and epoch, samples outside the grid."""
    rng = np.random.default_rng(3)
    n = 400
    ranges = pd.DataFrame({"t": rng.uniform(-1.0, 21.0, n), "anchor_id": rng.choice(["U10", "U02", "U01", "B7"], n),
                           "range_m": rng.uniform(0.5, 20.0, n), "status": 0, "line": 1})
    times = 0.5 * np.arange(1, 41)
    epochs = build_epochs(ranges, ranges.iloc[:0].rename(columns={"range_m": "rss_dbm"}), 0.5, times=times)
    inside = (ranges["t"] > 0.0) & (ranges["t"] <= 20.0)
    expected = ranges[inside].assign(epoch=np.ceil(ranges["t"][inside] / 0.5 - 1e-12).astype(int) - 1) \
        .groupby(["epoch", "anchor_id"])["range_m"].mean()
    got = pd.Series([v for e in epochs for v in e.ranges],
                    index=pd.MultiIndex.from_tuples([(k, a) for k, e in enumerate(epochs) for a in e.range_ids]))
    assert got.index.tolist() == expected.index.tolist()
    np.testing.assert_allclose(got.to_numpy(), expected.to_numpy(), rtol=1e-13)


def test_paper_d_on_a_simulated_run(campaign, simulated_run):
    from wsnloc.io.newcom import ingest_run

    tables, _ = ingest_run(simulated_run, campaign)
    estimates = paper_d.run(RunData(tables, campaign, RSS_MODEL), SPEC, LABEL)
    metrics = paper_d.run_metrics(estimates, tables["truth"])
    assert set(metrics["stage"]) == {"raw", "velocity", "kalman"} and len(metrics) == 2 * 4 * 3
    uwb = metrics[(metrics["localizer"] == "multilateration") & (metrics["technique"] == "uwb")
                  & (metrics["stage"] == "raw")]
    # metre-level: the link budget's NLOS leading-edge errors (docs/simulation.md); a broken solver gives many metres
    assert uwb["rmse"].iloc[0] < 2.0 and uwb["availability"].iloc[0] > 0.9
    rows = paper_d.results_rows(metrics.assign(run="run-01"), "newcom/constant", SPEC)
    frame = results.frame(rows)
    assert set(frame["table"]) == {"Table 1", "Table 2", "Table 3"}
    claims = paper_d.claims({"newcom/constant": metrics.assign(run="run-01")})
    assert len(claims) == 6 and all(c["verdict"] == "inconclusive" for c in claims)     # one run: no interval


@pytest.mark.parametrize("speed_input", [False, True])
def test_paper_d_run_all_equals_its_cells_registry_frames_stacked(campaign, simulated_run, speed_input):
    """run_all stacks each cell's arrays (batched.cell_tracks, no registry.finish frame per
    cell): the same t, x, y, labels and scores, exactly, as stacking every cell's
    registry.run frame (the KF with and without the velocity algorithm's speed)."""
    from wsnloc.io.newcom import ingest_run
    from wsnloc.metrics.tracking import score

    spec = {**SPEC, "estimators": {**SPEC["estimators"],
                                   "kalman": {**SPEC["estimators"]["kalman"], "speed_input": speed_input}}}
    tables, _ = ingest_run(simulated_run, campaign)
    got = paper_d.run(RunData(tables, campaign, RSS_MODEL), spec, LABEL)
    data = RunData(tables, campaign, RSS_MODEL)
    cells = paper_d.cell_list(spec, LABEL)
    frames = [registry.run(name, data, p, where="experiments.paper_d") for *_, name, p in cells]
    labels = {key: np.repeat([cell[k] for cell in cells], [len(f) for f in frames])
              for k, key in enumerate(("localizer", "technique", "stage"))}
    expected = score(pd.concat([f[["t", "x", "y"]] for f in frames], ignore_index=True).assign(**labels),
                     tables["truth"])
    pd.testing.assert_frame_equal(got, expected, check_exact=True)


def test_track_of_an_estimator_frame_is_registry_finish():
    """batched.Track.of: the columns a frame lacks NaN, rows sorted by time (stable)."""
    from wsnloc.estimators import batched

    frame = pd.DataFrame({"t": [2.0, 1.0, 1.0, 3.0], "x": [0.0, 1.0, 2.0, 3.0], "y": [4.0, 5.0, 6.0, 7.0],
                          "n_meas": [1, 2, 3, 4]})
    frame.attrs["resets"] = 2
    track = batched.Track.of(frame)
    finished = registry.finish(frame)
    np.testing.assert_array_equal(track.rows, finished[core.COLUMNS].to_numpy(float))
    assert track.rows[:, 1].tolist() == [1.0, 2.0, 0.0, 3.0] and track.attrs == {"resets": 2}


def test_speed_input_metrics_measure_the_fed_speed_against_truth_and_the_kf_without_it(campaign, simulated_run):
    """speed_input_metrics: per KF cell the velocity algorithm's speed (what the KF is fed)
    against the true speed at the same fixes, and the KF's RMSE without that input, which is
    the speed_input: false cell's own RMSE; noisy fixes make the fed speed too high (eq. 1 adds
    every step's noise to the path length). No speed input: no rows. The results rows carry
    them in Table 3 and explain_d quotes them in the KF claim's mechanism."""
    from wsnloc.experiments import why
    from wsnloc.io.newcom import ingest_run

    tables, _ = ingest_run(simulated_run, campaign)
    data = RunData(tables, campaign, RSS_MODEL)
    fed = {**SPEC, "estimators": {**SPEC["estimators"], "kalman": {**SPEC["estimators"]["kalman"], "speed_input": True}}}
    speed = paper_d.speed_input_metrics([data], fed, LABEL)[0]
    assert len(speed) == 8 and set(speed["stage"]) == {"kalman"}
    assert (speed["true_speed_mps"].between(0.0, 0.6)).all()              # the campaign's carts: 0-0.5 m/s
    assert (speed["speed_bias_mps"] > 0.1).all(), speed                   # metre-level fixes every 0.5 s
    np.testing.assert_allclose(speed["speed_bias_mps"], speed["speed_input_mps"] - speed["true_speed_mps"], atol=1e-12)
    plain = paper_d.run_metrics(paper_d.run(data, SPEC, LABEL, ("kalman",)), tables["truth"])
    np.testing.assert_allclose(speed["rmse_without_speed_m"], plain["rmse"], rtol=1e-12)
    assert (speed["speed_input_share"] > 0.5).all()                       # all but the window's first fixes
    unfed = paper_d.speed_input_metrics([data], SPEC, LABEL)[0]
    assert unfed.empty and list(unfed.columns) == paper_d.CELL_KEY

    metrics = paper_d.run_metrics(paper_d.run(data, fed, LABEL), tables["truth"]).merge(speed, how="left")
    frame = results.frame(paper_d.results_rows(metrics.assign(run="run-01"), LABEL, fed))
    table3 = frame[(frame["table"] == "Table 3") & (frame["column"] == "F-mix")]
    assert table3[table3["row"] == paper_d.SPEEDLESS_ROW]["value"].iloc[0] == pytest.approx(
        plain[(plain["localizer"] == "minmax") & (plain["technique"] == "fmix")]["rmse"].iloc[0])
    assert set(table3[table3["row"] == "Kalman filter"]["metric"]) >= set(paper_d.SPEED_INPUT_METRICS[:-1])
    per_run = {LABEL: metrics.assign(run="run-01")}
    records = [{"claim": c["claim"], "verdict": "does not hold"} for c in paper_d.claims(per_run)]
    kf = [r for r in why.explain_d(records, per_run, 0.5, 6) if r["claim"].startswith("The Kalman filter")][0]
    fmix = speed[(speed["localizer"] == "minmax") & (speed["technique"] == "fmix")].iloc[0]
    assert f"speed fed {fmix['speed_input_mps']:.2f} m/s against a true {fmix['true_speed_mps']:.2f} m/s" in kf["why"]


def test_speed_rows_of_a_fed_kf_never_vanish(campaign, simulated_run):
    """A KF cell fed the speed (config) always has its Table 3 speed rows: NaN over runs without
    a speed estimate at any fix, with speed_input_share 0 saying why; metrics that lack them
    (speed_input_metrics not merged) are an error naming the cell. Not fed: no speed rows. The
    speed measured is trackers.fix_source's, the KF's own input."""
    from wsnloc.estimators import trackers
    from wsnloc.io.newcom import ingest_run

    tables, _ = ingest_run(simulated_run, campaign)
    data = RunData(tables, campaign, RSS_MODEL)
    fed = {**SPEC, "estimators": {**SPEC["estimators"], "kalman": {**SPEC["estimators"]["kalman"], "speed_input": True}}}
    speed = paper_d.speed_input_metrics([data], fed, LABEL)[0]
    p = [cell for cell in paper_d.cell_list(fed, LABEL, ("kalman",)) if cell[:2] == ("minmax", "fmix")][0][4]
    source = trackers.fix_source(data, p)
    fmix = speed[(speed["localizer"] == "minmax") & (speed["technique"] == "fmix")].iloc[0]
    assert fmix["speed_input_mps"] == pytest.approx(np.nanmean(source.speed[source.has_fix()]), rel=0.05)

    plain = paper_d.run_metrics(paper_d.run(data, fed, LABEL), tables["truth"])
    without_speed = speed.assign(speed_input_share=0.0, **{m: np.nan for m in paper_d.SPEED_INPUT_METRICS[1:-1]})
    frame = results.frame(paper_d.results_rows(plain.merge(without_speed, how="left").assign(run="run-01"), LABEL, fed))
    kf = frame[(frame["table"] == "Table 3") & (frame["row"] == "Kalman filter") & (frame["column"] == "F-mix")]
    row = kf.set_index("metric")
    assert row.loc["speed_input_share", "value"] == 0 and np.isnan(row.loc["speed_input_mps", "value"])
    assert row.loc["speed_input_mps", "runs"] == 0
    with pytest.raises(ValueError, match="Min-Max narrowband fixes is fed the speed .* lack speed_input_share"):
        paper_d.results_rows(plain.assign(run="run-01"), LABEL, fed)
    unfed = results.frame(paper_d.results_rows(plain.assign(run="run-01"), LABEL, SPEC))
    assert not unfed["metric"].isin(paper_d.SPEED_INPUT_METRICS).any()
