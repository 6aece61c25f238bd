"""Cells stepped together (batched, core.epoch_loop with the array EKF bank) give registry.run's
estimates, run by run (registry.run of one cell runs the filter objects of core.FilterBank)."""


import numpy as np
import pandas as pd
import pytest

from synthetic import SQUARE, bursts, run_data, tables_for, walk
from conftest import ROOT
from wsnloc.campaign import Campaign
from wsnloc.estimators import array_ekf, batched, bayes, core, registry
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_a, paper_c
from wsnloc.filters.kalman import KalmanFilter
from wsnloc.filters.measurement_models import RangeModel
from wsnloc.io.cricket import ingest_run as ingest_cricket
from wsnloc.metrics.tracking import score
from wsnloc.io.newcom import ingest_run
from wsnloc.sim.cricket import simulate_run as simulate_cricket
from wsnloc.signal.resample import resample_imu
from wsnloc.sim.newcom import simulate_run
from wsnloc.sim.seeding import run_seed_sequence

RSS_MODEL = {"p0_dbm": -50.0, "path_loss_exponent": 3.0, "sigma_db": 5.0, "d0_m": 1.0}
SPEC_A = {"scenarios": ["newcom/constant"],   # experiments.paper_a as in config/config.yaml
          "parameters": dict(epoch_s=0.5, max_range_m=50.0, range_sigma_m=0.3, rss_calibration="configured",
                             **RSS_MODEL, accel_sigma_mps2=0.3, initial_speed_sigma_mps=0.3),
          "estimators": {"Table I": {"estimator": "ekf"}, "Table II": {"estimator": "ekf", "motion_detection": True}},
          "rows": [{"measurements": "toa", "anchors": "UWB=12"}, {"measurements": "toa", "anchors": "UWB=9"},
                   {"measurements": "rss", "anchors": "ZigBee=21"},
                   {"measurements": "hybrid", "anchors": "UWB=9+ZigBee=17"}]}
SPEC_C = {"scenarios": ["cricket/speed_40"], "table_1_subset": "6: B1..B6",   # experiments.paper_c
          "table_2_subsets": ["3: B1,B3,B4", "4: B1,B3,B4,B6", "6: B1..B6"], "table_2_scenario": "cricket/speed_40",
          "parameters": dict(epoch_s=0.5, range_sigma_m=0.05, max_range_m=12.0, accel_sigma_mps2=0.3,
                             initial_sigma_m=0.5, initial_speed_sigma_mps=0.3),
          "estimators": {"P": {"estimator": "ekf", "motion": "p"}, "PV": {"estimator": "ekf"},
                         "PVA": {"estimator": "ekf", "motion": "pva", "accel_sigma_mps2": 0.1}}}
LABEL_A = "newcom/constant"


def _arrays(monkeypatch, call):
    """call() with every group of bare epoch-mode EKF cells, even of one or two cells, run as the
    array EKF (array_ekf.ArrayEKF); registry.run of one cell outside it runs the filter objects."""
    with monkeypatch.context() as patch:
        patch.setattr(bayes, "ARRAY_MIN_CELLS", 1)
        return call()


@pytest.fixture(scope="module")
def simulated_runs(campaign, tmp_path_factory):
    """Three simulated Newcom++ runs (two scenarios, so the epoch grids differ in length),
    ingested, with the 5 Hz IMU the PVA model reads."""
    out = []
    for k, scenario in enumerate(["constant", "variable", "constant"]):
        raw = simulate_run(campaign, scenario, run_seed_sequence(3, "newcom", scenario, k),
                           tmp_path_factory.mktemp("batched") / f"run-{k}")
        tables, _ = ingest_run(raw, campaign)
        tables["imu_5hz"] = resample_imu(tables["imu"], 5.0, 500.0, 0.1, 8.0)
        model = dict(RSS_MODEL, p0_dbm=RSS_MODEL["p0_dbm"] + k)       # per-run calibrated RSS models differ
        out.append((tables, model, f"run-{k}"))
    return out


def _datas(runs, campaign):
    return [RunData(tables, campaign, model, name) for tables, model, name in runs]


def _assert_same(batch, single):
    assert len(batch) == len(single)
    for b, s in zip(batch, single):
        assert b.attrs == s.attrs
        pd.testing.assert_frame_equal(b, s, check_exact=False, rtol=0, atol=1e-9)


CASES = {
    "toa pv": {"measurements": "toa", "anchors": "UWB=12", "motion": "pv"},
    "rss p": {"measurements": "rss", "anchors": "ZigBee=21", "motion": "p", "rss_calibration": "other_run"},
    "hybrid pv, motion detection": {"measurements": "hybrid", "anchors": "UWB=9+ZigBee=17", "motion": "pv",
                                    "motion_detection": True, "rss_calibration": "other_run"},
    "toa pva": {"measurements": "toa", "anchors": "UWB=12", "motion": "pva"},
    "toa pv, short coasting, window initiator": {"measurements": "toa", "anchors": "UWB=9", "motion": "pv",
                                                 "max_coast_s": 0.4, "init_window_s": 1.5},
}


@pytest.mark.parametrize("case", CASES)
def test_batched_equals_registry_run_one_run_at_a_time(campaign, simulated_runs, case, monkeypatch):
    params = dict(CASES[case], update="epoch", preliminary_filter=True, max_range_m=50.0)
    single = [registry.run("ekf", data, params) for data in _datas(simulated_runs, campaign)]
    batch = batched.run_many("ekf", _datas(simulated_runs, campaign), params)
    _assert_same(batch, single)
    alone = [_arrays(monkeypatch, lambda: registry.run("ekf", data, params)) for data in _datas(simulated_runs, campaign)]
    _assert_same(alone, single)
    assert all(len(s) > 100 for s in single)


def test_coasting_resets_are_counted_per_run(monkeypatch):
    """A gap longer than the coasting limit in one run only: that run resets, the other does not."""
    t, ids = bursts(60.0)
    gap = (t > 20.0) & (t < 35.0)
    with_gap = run_data(tables_for(t[~gap], ids[~gap], walk))
    without = run_data(tables_for(t, ids, walk))
    params = {"anchors": "all", "max_coast_s": 5.0}
    batch = _arrays(monkeypatch, lambda: batched.run_many("ekf", [with_gap, without], params))
    single = [registry.run("ekf", d, params) for d in (with_gap, without)]
    _assert_same(batch, single)
    assert [b.attrs["resets"] for b in batch] == [1, 0]


def test_noise_free_ranges_are_tracked(monkeypatch):
    """The epoch mode outputs at t_k what was measured at t_k - T (the ranges of the bursts)."""
    t, ids = bursts(60.0)
    (est,) = _arrays(monkeypatch, lambda: batched.run_many("ekf", [run_data(tables_for(t, ids, walk))], {"anchors": "all"}))
    error = np.hypot(*(est[["x", "y"]].to_numpy() - walk(est["t"].to_numpy() - 0.5)).T)
    assert np.median(error[20:]) < 0.02


def test_other_estimators_fall_back_to_one_run_at_a_time():
    t, ids = bursts(20.0)
    datas = [run_data(tables_for(t, ids, walk))]
    for name, params in (("tracker", {}), ("minmax", {}), ("velocity_tracker", {}),
                         ("ekf", {"update": "sequential"})):
        params = dict(params, anchors="all")
        _assert_same(batched.run_many(name, datas, params), [registry.run(name, datas[0], params)])
    assert not array_ekf.supports(registry.get("tracker").resolve({}))
    assert not array_ekf.supports(registry.get("ekf").resolve({}))                                # gated
    plain = registry.get("ekf").resolve({"gate_probability": 0.0})                                 # papers A, C
    assert array_ekf.supports(bayes.resolve_update(datas[0], plain))                                # bursts: epoch


def test_padded_measurements_change_nothing():
    """One update with 3 real ranges equals the same update padded to 8 rows."""
    rng = np.random.default_rng(2)
    x, P = rng.normal(5, 1, (1, 4)), np.eye(4)[None] * 2.0
    anchors = np.array(list(SQUARE.values())[:3])

    def measurements(width):
        m = array_ekf.Measurements.empty(1, 1, width)
        m.count[0, 0] = 3
        m.anchors[0, 0, :3], m.variance[0, 0, :3], m.z[0, 0, :3] = anchors, 0.09, [7.0, 12.0, 15.0]
        return m.at(0, np.array([0]))

    narrow, wide = array_ekf.update(x, P, measurements(3)), array_ekf.update(x, P, measurements(8))
    for a, b in zip(narrow, wide):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 4, 6])
def test_array_update_is_each_filters_update(dim):
    """The array EKF's update (filters.kalman.joseph_update over a run axis) gives, run by run,
    what one filter's update (KalmanFilter.update, the same function without a batch axis)
    gives with that run's H = [H_p, 0] and R = diag(variance): x, P and NIS, for P, PV and
    PVA states and mixed variances; a run whose measurement is not finite keeps its prior."""
    rng = np.random.default_rng(dim)
    runs, width = 5, 7
    x = rng.normal(0.0, 3.0, (runs, dim))
    root = rng.normal(0.0, 1.0, (runs, dim, dim))
    P = root @ np.swapaxes(root, 1, 2) + 0.1 * np.eye(dim)
    m = array_ekf.Measurements.empty(runs, 1, width)
    m.count[:, 0] = [7, 3, 1, 7, 5]
    m.anchors[:, 0] = rng.uniform(-10, 10, (runs, width, 2))
    m.variance[:, 0] = rng.choice([0.09, 25.0], (runs, width))
    m.z[:, 0] = rng.uniform(1, 15, (runs, width))
    m.z[3, 0, 2] = np.nan
    new_x, new_P, nis, ok = array_ekf.update(x, P, m.at(0, np.arange(runs)))
    np.testing.assert_array_equal(ok, [True, True, True, False, True])
    for r in range(runs):
        n = m.count[r, 0]
        filt = KalmanFilter(x[r], P[r], np.eye(dim), np.zeros((dim, dim)), np.zeros((n, dim)), np.eye(n))
        model = RangeModel(m.anchors[r, 0, :n], np.sqrt(m.variance[r, 0, :n]))
        filt.update(m.z[r, 0, :n], model.jacobian(x[r]), model.R(), model.h(x[r]))
        assert filt.guards.skipped == (not ok[r])
        np.testing.assert_allclose(new_x[r], filt.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(new_P[r], filt.P, rtol=0, atol=1e-12)
        np.testing.assert_allclose(nis[r], filt.nis if ok[r] else np.nan, rtol=1e-12)
    np.testing.assert_array_equal(new_x[3], x[3])


def test_cells_of_different_kinds_subsets_and_models_in_one_call_equal_registry_run(campaign, simulated_runs):
    """run_cells steps the cells sharing a motion model together, whatever their measurement
    kinds and anchor subsets (padded to the widest epoch), and the others in their own group."""
    datas = _datas(simulated_runs, campaign)
    rows = [{"measurements": "toa", "anchors": "UWB=9"}, {"measurements": "rss", "anchors": "ZigBee=21"},
            {"measurements": "hybrid", "anchors": "UWB=12+ZigBee=21"},
            {"measurements": "toa", "anchors": "UWB=12", "motion": "p"}]
    cells = [(data, dict(row, update="epoch", rss_calibration="other_run")) for row in rows for data in datas]
    _assert_same(batched.run_cells("ekf", cells), [registry.run("ekf", d, q) for d, q in cells])


@pytest.mark.parametrize("params", [{"anchors": "UWB=12"}, {"anchors": "UWB=9", "solver": "minmax", "k_smallest": 6}])
def test_batched_kf_over_fixes_equals_registry_run(campaign, simulated_runs, params):
    single = [registry.run("kf_tracker", data, params) for data in _datas(simulated_runs, campaign)]
    batch = batched.run_many("kf_tracker", _datas(simulated_runs, campaign), params)
    _assert_same(batch, single)
    assert all(len(s) > 100 for s in single)


def test_kf_cells_with_different_matrices_and_fixes_equal_registry_run(campaign, simulated_runs):
    """run_cells groups kf_tracker cells by their KF matrices; each cell keeps its own fixes."""
    datas = _datas(simulated_runs, campaign)
    params = [{"anchors": "UWB=12"}, {"anchors": "UWB=9", "solver": "minmax"},
              {"anchors": "UWB=12", "accel_sigma_mps2": 1.0}]
    cells = [(data, q) for q in params for data in datas]
    _assert_same(batched.run_cells("kf_tracker", cells), [registry.run("kf_tracker", d, q) for d, q in cells])


def test_batched_kf_over_fixes_with_a_gap_in_one_run():
    t, ids = bursts(40.0)
    gap = (t > 10.0) & (t < 20.0)
    datas = [run_data(tables_for(t[~gap], ids[~gap], walk)), run_data(tables_for(t[5:], ids[5:], walk))]
    single = [registry.run("kf_tracker", d, {"anchors": "all"}) for d in datas]
    _assert_same(batched.run_many("kf_tracker", datas, {"anchors": "all"}), single)


def test_paper_a_runs_and_rows_stepped_together_equal_registry_run(campaign, simulated_runs):
    """paper_a.run_all steps its cells (rows x with / without motion detection) of every run
    together, and splits them back per run."""
    datas = _datas(simulated_runs[:2], campaign)
    params = [paper_a.cell_params(SPEC_A, LABEL_A, table, row) for row in SPEC_A["rows"] for table in paper_a.TABLES]
    cells = [(data, q) for data in datas for q in params]
    single = [registry.run("ekf", data, q, where="experiments.paper_a") for data, q in cells]
    _assert_same(batched.run_cells("ekf", cells, where="experiments.paper_a"), single)
    scored = paper_a.run_all(datas, SPEC_A, LABEL_A)
    n = len(params)
    assert [len(s) for s in scored] == [sum(len(f) for f in single[:n]), sum(len(f) for f in single[n:])]


def test_paper_a_run_all_equals_its_cells_frames_labelled_and_concatenated(campaign, simulated_runs):
    """run_all stacks each run's cell arrays into one frame: the same frame (values exactly,
    dtypes, column order, attrs) as the former pd.concat of every cell's run_cells frame with
    its row and table assigned, then scored; and registry.run's cells to 1e-9."""
    cells = [(row, table) for row in SPEC_A["rows"] for table in paper_a.TABLES]
    params = [paper_a.cell_params(SPEC_A, LABEL_A, table, row) for row, table in cells]
    for datas in (_datas(simulated_runs, campaign), _datas(simulated_runs, campaign)[1:]):
        frames = batched.run_cells("ekf", [(d, q) for d in datas for q in params], where="experiments.paper_a")
        single = [registry.run("ekf", d, q, where="experiments.paper_a") for d in datas for q in params]
        for i, (data, got) in enumerate(zip(datas, paper_a.run_all(datas, SPEC_A, LABEL_A))):
            for tracks, exact in ((frames, True), (single, False)):
                mine = tracks[i * len(cells):(i + 1) * len(cells)]
                expected = score(pd.concat([f.assign(row=paper_a.row_label(row), table=table)
                                            for f, (row, table) in zip(mine, cells)], ignore_index=True),
                                 data.table("truth"))
                pd.testing.assert_frame_equal(got, expected, check_exact=exact, rtol=0, atol=1e-9)
                assert got.attrs == expected.attrs


def test_track_frames_equal_registry_finish_of_the_filter_frame(campaign, simulated_runs):
    """Track.finished() is registry.finish(Track.frame()); Track.of reads a frame back."""
    data = _datas(simulated_runs, campaign)[0]
    p = registry.get("ekf").resolve({"update": "epoch", "motion_detection": True}, "")
    track = bayes.run_filters([(data, p)])[0]
    assert track.frame()["n_meas"].dtype == int
    finished = registry.finish(track.frame())
    pd.testing.assert_frame_equal(track.finished(), finished, check_exact=True)
    assert track.finished().attrs == finished.attrs == track.attrs
    again = batched.Track.of(finished)
    np.testing.assert_array_equal(again.rows, track.rows)
    assert again.attrs == track.attrs


def test_paper_c_models_and_subsets_of_one_run_equal_registry_run(tmp_path):
    """P, PV, PVA on three beacon subsets of a simulated Cricket run: three groups (one per
    motion model) of three subsets each."""
    cricket = Campaign.load(ROOT / "config" / "campaigns" / "cricket.yaml")
    raw = simulate_cricket(cricket, "speed_40", run_seed_sequence(4, "cricket", "speed_40", 1), tmp_path / "run")
    tables, _ = ingest_cricket(raw, cricket)
    tables["imu_5hz"] = resample_imu(tables["imu"], 5.0, 500.0, 0.1, 8.0)
    data = RunData(tables, cricket, None, "run-1")
    params = [paper_c.cell_params(SPEC_C, "cricket/speed_40", model, subset) for subset in SPEC_C["table_2_subsets"]
              for model in paper_c.MODELS]
    single = [registry.run("ekf", data, q, where="experiments.paper_c") for q in params]
    frames = batched.run_cells("ekf", [(data, q) for q in params], where="experiments.paper_c")
    _assert_same(frames, single)
    assert all(len(s) > 50 for s in single)
    # run_all builds one frame per run from the arrays (batched.stacked): the former pd.concat
    # of every cell's run_cells frame with its model and subset assigned, then scored
    cells = [(model, subset) for subset in SPEC_C["table_2_subsets"] for model in paper_c.MODELS]
    expected = score(pd.concat([f.assign(model=model, subset=subset) for f, (model, subset) in zip(frames, cells)],
                               ignore_index=True), data.table("truth"))
    got = paper_c.run(data, SPEC_C, "cricket/speed_40", SPEC_C["table_2_subsets"])
    pd.testing.assert_frame_equal(got, expected, check_exact=True)
    assert got.attrs == expected.attrs


def test_stacked_equals_the_labelled_frames_concatenated(campaign, simulated_runs):
    """stacked(tracks, labels, columns) is pd.concat of each track's finished frame (those
    columns) with its labels assigned: values exactly, dtypes, column order, attrs (kept only
    when every track has the same non-empty attrs, as pd.concat keeps them)."""
    datas = _datas(simulated_runs, campaign)[:2]
    p = {"update": "epoch", "anchors": "UWB=12"}
    tracks = batched.cell_tracks("ekf", [(d, p) for d in datas] + [(datas[0], dict(p, motion="p"))])
    tracks.append(batched.Track(tracks[0].rows, {**tracks[0].attrs, "resets": -1}))     # other attrs
    labels = {"model": ["PV", "PV", "P", "PV"], "run": ["a", "b", "a", "c"]}
    for columns in (tuple(core.COLUMNS), ("t", "x", "y")):
        for chosen in ([0, 1, 2], [0, 2], [1], [0, 3]):
            picked = [tracks[i] for i in chosen]
            names = {name: [values[i] for i in chosen] for name, values in labels.items()}
            expected = pd.concat([t.finished()[list(columns)].assign(**{n: v[j] for n, v in names.items()})
                                  for j, t in enumerate(picked)], ignore_index=True)
            got = batched.stacked(picked, names, columns)
            pd.testing.assert_frame_equal(got, expected, check_exact=True)
            assert got.attrs == expected.attrs
            assert bool(got.attrs) == (len({repr(tracks[i].attrs) for i in chosen}) == 1)


def test_run_cells_falls_back_for_sequential_rows():
    t, ids = bursts(20.0)
    data = run_data(tables_for(t, ids, walk))
    rows = [{"anchors": "all"}, {"anchors": "all", "update": "sequential"}]
    _assert_same(batched.run_cells("ekf", [(data, row) for row in rows]), [registry.run("ekf", data, row) for row in rows])
