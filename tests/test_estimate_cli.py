"""`wsnloc estimators` and `wsnloc estimate`: the registry and one estimator on one raw run."""

import json

import numpy as np
import pandas as pd
import pytest

from synthetic import SQUARE, bursts, one_at_a_time, tables_for, walk
from wsnloc.cli import main


def write_generic(folder, tables, shuffle_seed=None):
    """A generic-format run directory (CSV) from canonical tables; rows shuffled if asked."""
    folder.mkdir(parents=True)
    ranges = tables["ranges"][["t", "anchor_id", "range_m"]]
    if shuffle_seed is not None:
        ranges = ranges.sample(frac=1.0, random_state=shuffle_seed)
    ranges.to_csv(folder / "ranges.csv", index=False, float_format="%.6f")
    tables["truth"][["t", "x", "y"]].to_csv(folder / "truth.csv", index=False, float_format="%.6f")
    tables["anchors"][["anchor_id", "tech", "x", "y"]].to_csv(folder / "anchors.csv", index=False)
    return folder


def test_estimators_lists_the_registry_as_json(capsys):
    assert main(["estimators", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert len(listed) >= 12 and {"name", "parameters"} <= set(listed[0])
    ekf = next(e for e in listed if e["name"] == "ekf")
    motion = next(p for p in ekf["parameters"] if p["name"] == "motion")
    assert motion["default"] == "pv" and motion["choices"] == ["p", "pv", "pva", "odometry"]
    dimensions = next(p for p in ekf["parameters"] if p["name"] == "dimensions")
    assert dimensions["default"] == 2 and {"odometry_speed_sigma_mps", "odometry_yaw_rate_sigma_rps"} <= {
        p["name"] for p in ekf["parameters"]}
    assert main(["estimators"]) == 0 and "tracker (default of `wsnloc estimate`)" in capsys.readouterr().out


def test_estimate_tracks_ranges_one_anchor_at_a_time_with_default_settings(tmp_path, capsys):
    """Acceptance: 4 anchors, about 2 Hz in total, one anchor at a time, unsorted rows and a
    60 s gap; the same walk ranged in bursts (4 ranges every 2 s) is the reference."""
    rng = np.random.default_rng(21)
    duration, gap = 1500.0, (700.0, 760.0)
    times, ids = one_at_a_time(duration, 2.0, rng, SQUARE, gap)
    single = write_generic(tmp_path / "single" / "run", tables_for(times, ids, walk, SQUARE, 0.1, rng), 3)
    t_burst, id_burst = bursts(duration, 2.0, SQUARE)
    keep = (t_burst < gap[0]) | (t_burst > gap[1])
    burst = write_generic(tmp_path / "burst" / "run", tables_for(t_burst[keep], id_burst[keep], walk, SQUARE, 0.1, rng))
    for run in (single, burst):
        assert main(["estimate", "--format", "generic", str(run), "--out", str(run.parent / "out")]) == 0
        if run is single:                    # the shuffled rows are said to be sorted, as ingest says it
            printed = capsys.readouterr()
            said = printed.out + printed.err
            assert "ranges.csv: " in said and "row(s) out of time order (sorted)" in said
    a = json.loads((single.parent / "out" / "metrics.json").read_text())
    b = json.loads((burst.parent / "out" / "metrics.json").read_text())
    assert set(a) >= {"rmse_m", "median_m", "p75_m", "p90_m", "p95_m", "max_m", "n", "availability"}
    assert a["availability"] >= 0.95
    assert a["median_m"] <= 2.0 * b["median_m"]
    estimates = pd.read_parquet(single.parent / "out" / "estimates.parquet")
    assert {"t", "x", "y"} <= set(estimates.columns) and estimates["t"].is_monotonic_increasing


def test_estimate_on_a_simulated_newcom_run_with_another_estimator(simulated_run, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["estimate", "--format", "newcom", str(simulated_run), "--out", str(out), "--estimator", "fmix",
                 "--set", "solver=multilateration", "--set", "rss_calibration=configured",
                 "--set", "p0_dbm=-50", "--set", "path_loss_exponent=3", "--set", "k_smallest=6"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["median_m"] < 1.5 and metrics["availability"] > 0.9
    assert "fmix:" in capsys.readouterr().out


def test_estimate_refuses_unknown_parameters_and_estimators(simulated_run, tmp_path, capsys):
    assert main(["estimate", "--format", "newcom", str(simulated_run), "--out", str(tmp_path / "a"),
                 "--set", "accel=1"]) == 2
    assert "'--set.accel': unknown parameter" in capsys.readouterr().err
    assert main(["estimate", "--format", "newcom", str(simulated_run), "--out", str(tmp_path / "b"),
                 "--estimator", "kalman"]) == 2
    assert "unknown estimator 'kalman'" in capsys.readouterr().err


def test_estimate_fails_loudly_when_there_is_nothing_to_estimate(tmp_path, capsys):
    rng = np.random.default_rng(1)
    times = np.sort(rng.uniform(0, 100, 200))
    run = write_generic(tmp_path / "run", tables_for(times, np.full(200, "A1", dtype=object), walk, SQUARE, 0.1, rng))
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "no estimates" in err and "from 1 anchors" in err


@pytest.mark.parametrize("estimator", ["dr_sskf", "ekf_pva"])
def test_estimate_runs_the_imu_estimators_with_a_resampled_imu(simulated_run, tmp_path, estimator):
    out = tmp_path / estimator
    assert main(["estimate", "--format", "newcom", str(simulated_run), "--out", str(out),
                 "--estimator", estimator]) == 0
    assert json.loads((out / "metrics.json").read_text())["median_m"] < 2.0


def test_estimate_calibrates_ranges_on_a_donor_run(tmp_path):
    """`--calibration DONOR --set range_calibration=other_run`: per-anchor offsets fitted on
    the donor run correct the biased ranges of the run (issue 13)."""
    offsets = {"A1": 0.5, "A2": -0.3, "A3": 0.2, "A4": -0.45}
    runs = {}
    for name, seed in (("donor", 31), ("run", 32)):
        rng = np.random.default_rng(seed)
        times, ids = one_at_a_time(300.0, 4.0, rng, SQUARE)
        tables = tables_for(times, ids, walk, SQUARE, 0.1, rng)
        tables["ranges"]["range_m"] += tables["ranges"]["anchor_id"].map(offsets)
        runs[name] = write_generic(tmp_path / name / "run", tables)
    out = {}
    for label, extra in (("plain", ["--set", "self_fit=none"]), ("calibrated", ["--calibration", str(runs["donor"]),
                                                        "--set", "range_calibration=other_run"])):
        assert main(["estimate", "--format", "generic", str(runs["run"]), "--out", str(tmp_path / label),
                     "--set", "range_sigma_m=0.1", *extra]) == 0
        out[label] = json.loads((tmp_path / label / "metrics.json").read_text())
    calibrated = out["calibrated"]
    assert calibrated["range_calibration"] == f"fitted on {runs['donor']}"
    fitted = dict(item.split("=") for item in calibrated["calibrated_offsets_m"].split(";"))
    assert all(abs(float(fitted[a]) - b) < 0.05 for a, b in offsets.items())
    assert calibrated["median_m"] < 0.5 * out["plain"]["median_m"]
    assert out["plain"]["range_calibration"] == "none" and "calibrated_scale" not in out["plain"]


def test_estimate_refuses_a_donor_it_cannot_use(tmp_path, capsys):
    rng = np.random.default_rng(4)
    times, ids = bursts(20.0, 0.5, SQUARE)
    run = write_generic(tmp_path / "r" / "run", tables_for(times, ids, walk, SQUARE, 0.1, rng))
    # (--calibration alone now calibrates the tracker's ranges: tests/test_realdata.py; Min-Max on
    # ranges has nothing a donor could calibrate)
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "o"), "--estimator", "minmax",
                 "--calibration", str(run)]) == 2
    assert "calibrates nothing on a donor" in capsys.readouterr().err


def test_estimate_names_its_own_quarantine_options(tmp_path, capsys):
    """A run with 30% unusable range lines: `estimate` stops at the default limit (that of config
    ingest.max_quarantine_share) naming its option, not a config key it has no file for, and
    runs with the option raised."""
    from wsnloc.io.limits import DEFAULT_PER_FILE

    rng = np.random.default_rng(3)
    times, ids = bursts(120.0, 1.0, SQUARE)
    run = write_generic(tmp_path / "run", tables_for(times, ids, walk, SQUARE, 0.1, rng))
    lines = (run / "ranges.csv").read_text().splitlines()
    bad = int(0.3 * (len(lines) - 1))
    (run / "ranges.csv").write_text("\n".join(lines[:1] + [f"{t},A1,not-a-number" for t in range(bad)]
                                              + lines[1 + bad:]) + "\n")
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"more than option --max-quarantine-share-per-file = {DEFAULT_PER_FILE:.1%}" in err and "config" not in err
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out"),
                 "--max-quarantine-share", "0.5", "--max-quarantine-share-per-file", "0.5"]) == 0


def test_estimate_writes_the_self_fit_verdict_to_metrics_json(tmp_path):
    """metrics.json carries the self-fit's values and its verdict on the range correction
    (docs/realdata.md points users there)."""
    rng = np.random.default_rng(4)
    times, ids = one_at_a_time(300.0, 4.0, rng, SQUARE)
    tables = tables_for(times, ids, walk, SQUARE, 0.1, rng)
    tables["ranges"]["range_m"] = 1.07 * tables["ranges"]["range_m"]
    run = write_generic(tmp_path / "run", tables)
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out")]) == 0
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["self_fit_range_correction"] in ("applied", "not supported")
    assert {"self_fit_range_ll_gain", "self_fit_range_ll_penalty", "self_fit_run_sigma_m"} <= set(metrics)


def test_estimate_says_when_anchor_heights_meet_no_tag_height(tmp_path, capsys):
    """Anchors with z and no tag height (no meta.yaml): the tag is taken at z = 0 m, and the user is told."""
    rng = np.random.default_rng(5)
    times, ids = one_at_a_time(120.0, 4.0, rng, SQUARE)
    run = write_generic(tmp_path / "run", tables_for(times, ids, walk, SQUARE, 0.1, rng))
    anchors = pd.read_csv(run / "anchors.csv").assign(z=2.5)
    anchors.to_csv(run / "anchors.csv", index=False)
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out")]) == 0
    assert "no tag height" in capsys.readouterr().out
    (run / "meta.yaml").write_text("tag_height_m: 1.0\n")
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out2")]) == 0
    assert "no tag height" not in capsys.readouterr().out


def test_estimate_without_truth_writes_the_estimates_and_no_error_metrics(tmp_path, capsys):
    """truth.csv is optional: without it the estimates, the diagnosis and the self-fit are written
    (metrics.json has no error metrics) and the command succeeds."""
    rng = np.random.default_rng(3)
    times, ids = one_at_a_time(120.0, 4.0, rng, SQUARE)
    run = write_generic(tmp_path / "run", tables_for(times, ids, walk, SQUARE, 0.1, rng))
    (run / "truth.csv").unlink()
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    assert "diagnosis:" in printed and "not scored: the run has no truth" in printed
    estimates = pd.read_parquet(tmp_path / "out" / "estimates.parquet")
    assert len(estimates) > 100 and np.isfinite(estimates["x"]).all() and estimates["error_m"].isna().all()
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["estimator"] == "tracker" and "rmse_m" not in metrics


def test_estimate_says_when_a_fusing_estimator_has_no_rss_to_fuse(tmp_path, capsys):
    t, ids = bursts(30.0, 0.5, SQUARE)
    run = write_generic(tmp_path / "run", tables_for(t, ids, walk, SQUARE))
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out"), "--estimator", "pmix"]) == 0
    assert "the run has no RSS: pmix reads the ranges alone" in capsys.readouterr().out
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "o2"), "--estimator", "minmax"]) == 0
    assert "no RSS" not in capsys.readouterr().out


def test_estimate_says_which_ranges_the_preliminary_filter_left_out(tmp_path, capsys):
    """Ranges longer than max_range_m are left out by the preliminary filter: counted and said,
    with the setting that keeps them; none is left out when they are within it."""
    rng = np.random.default_rng(4)
    times, ids = one_at_a_time(120.0, 4.0, rng, SQUARE)
    tables = tables_for(times, ids, walk, SQUARE, 0.05, rng)
    tables["ranges"].loc[tables["ranges"].index[:7], "range_m"] = 150.0
    run = write_generic(tmp_path / "run", tables)
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out")]) == 0
    said = capsys.readouterr().out
    assert f"the preliminary filter left out 7 of {len(times)} ranges: 7 longer than max_range_m (100 m" in said
    assert main(["estimate", "--format", "generic", str(run), "--out", str(tmp_path / "out2"),
                 "--set", "max_range_m=200"]) == 0
    assert "preliminary filter" not in capsys.readouterr().out


def test_preliminary_filter_reasons_partition_what_it_drops():
    """Each dropped range under one reason (its first); the filter keeps exactly the others."""
    from wsnloc.estimators.run_data import preliminary_filter, preliminary_filter_reasons
    ranges = pd.DataFrame({"range_m": [5.0, -1.0, 0.0, 150.0, np.nan, 3.0, 200.0], "status": [0, 0, 0, 0, 0, 2, 1]})
    reasons = preliminary_filter_reasons(ranges, 100.0)
    assert {k: np.flatnonzero(v).tolist() for k, v in reasons.items()} == {
        "with a device status other than 0": [5, 6], "not finite": [4], "not positive": [1, 2],
        "longer than max_range_m": [3]}
    assert preliminary_filter(ranges, 100.0)["range_m"].tolist() == [5.0]
