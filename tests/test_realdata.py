"""Real-data conversion, references, diagnosis and the estimate CLI on hand-written runs."""

import json

import numpy as np
import pandas as pd
import pytest

from wsnloc import references
from wsnloc.cli import main
from wsnloc.diagnosis import diagnose_run, findings, metrics_of, report
from wsnloc.errors import ConfigError, IngestError
from wsnloc.estimators import registry
from wsnloc.estimators.auto import measurements_for
from wsnloc.estimators.run_data import RunData
from wsnloc.io.convert import QUARANTINE_FILE, convert_cucudasluv, convert_philotuxo, run_names
from wsnloc.io.generic import ingest_run, run_campaign
from wsnloc.workflow import without_missing_sources

RECEIVERS = {"aa01": ([0.0, 0.0, 2.3], "s1"), "aa02": ([10.0, 0.0, 1.22], "s2"), "aa03": ([0.0, 10.0, 2.3], "s3"),
             "aa04": ([10.0, 10.0, 1.22], "s4")}
BEACON = "e78f135624ce"
ORIENTATION = ",".join(["0.0"] * 9)


def _ble_site(root, lines):
    (root / "cnf").mkdir(parents=True)
    (root / "trk").mkdir()
    dongles = ", ".join(f'"{mac}": [{xyz}, 1, "{name}"]' for mac, (xyz, name) in RECEIVERS.items())
    (root / "cnf" / "site.dev").write_text(f"Dongles:{{{dongles}}}\nBeacons:{{}}\n")
    (root / "trk" / "walk_01_all_sensors.mbd").write_text("".join(line + "\n" for line in lines))


def _rss_line(t, mac, rss, x=5.0, y=5.0, beacon=BEACON):
    return f"{t},{mac},{beacon},{rss},{x},{y},1.8,{ORIENTATION}"


def test_ble_tracks_convert_with_every_bad_line_quarantined(tmp_path):
    good = [_rss_line(100.0 + 0.1 * k, mac, -70 - k % 5) for k in range(40) for mac in ("aa01", "aa02")]
    bad = ["100.5,aa01,e78f135624ce,-70", _rss_line(101.0, "ffff", -70), _rss_line(101.1, "aa01", -70, beacon="0000"),
           _rss_line(101.2, "aa02", "x")]
    _ble_site(tmp_path / "src", good + bad)
    [run] = convert_philotuxo(tmp_path / "src", tmp_path / "out")
    assert run.run_dir == tmp_path / "out" / "tracks" / "walk-01"
    assert run_names("philotuxo", tmp_path / "src") == {"tracks": ["walk-01"]}
    quarantine = pd.read_csv(run.run_dir / QUARANTINE_FILE)
    assert list(quarantine["line"]) == [81, 82, 83, 84] and len(run.quarantine) == 4
    assert {"4 fields", "unknown receiver", "not the tracked beacon", "not a number"} <= \
        {key for key in ("4 fields", "unknown receiver", "not the tracked beacon", "not a number")
         if quarantine["reason"].str.contains(key).any()}
    tables, inventory = ingest_run(run.run_dir)
    assert len(tables["rss"]) == 80 and set(tables["anchors"]["anchor_id"]) == {"s1", "s2", "s3", "s4"}
    assert tables["anchors"].set_index("anchor_id").loc["s2", "z"] == 1.22
    assert run_campaign(run.run_dir).tag_height_m == 1.8


def test_ble_conversion_stops_when_most_lines_are_bad(tmp_path):
    _ble_site(tmp_path / "src", [_rss_line(1.0, "aa01", -70)] + ["garbage"] * 5)
    with pytest.raises(IngestError, match="walk_01_all_sensors.mbd:2: 5 of 6 lines"):
        convert_philotuxo(tmp_path / "src", tmp_path / "out")


def _uwb_case(root):
    case = root / "Dynamic_measurements" / "LOS" / "Trajectory_A" / "Case_1"
    case.mkdir(parents=True)
    header = "%time,field.stamp,field.id,field.x,field.y,field.z,field.distanceFromTag,field.rssi,field.rssi_fp\n"
    for anchor, (x, y, z) in {"A3": (0.0, 0.0, 1.97), "A5": (10.0, 0.0, 0.5)}.items():
        rows = [f"0,{int((1 + 0.1 * k) * 1e9)},1,{x},{y},{z},{5 + 0.01 * k},-80.0,-82" for k in range(20)]
        rows[3] = rows[3].replace("-80.0", "-inf")           # bad RSSI: the range stays
        rows[5] = rows[5].replace(f",{5 + 0.05:.2f},", ",-1.0,") if anchor == "A3" else rows[5]
        (case / f"{anchor}.csv").write_text(header + "".join(r + "\n" for r in rows))
    truth = [f"{int((1 + 0.125 * k) * 1e9)},{0.1 * k},1.0,1.0,0" for k in range(17)]
    (case / "trajectory.csv").write_text("timestamp,x,y,z,heading_degrees\n" + "".join(r + "\n" for r in truth))
    (case / "LS.csv").write_text("timestamp,x,y,z\n" + "".join(f"{int((1 + 0.5 * k) * 1e9)},{0.05 * k * 4 + 3},"
                                                               f"5.0,1\n" for k in range(4)))
    (case / "RMSD_results.txt").write_text("LS RMSE: 1.5 m\nLS RMSE_2d: 1.25\n")


def test_uwb_case_converts_with_its_published_baselines(tmp_path):
    _uwb_case(tmp_path / "src")
    [run] = convert_cucudasluv(tmp_path / "src", tmp_path / "out")
    assert [q[3] for q in run.quarantine] == ["field.distanceFromTag '-1.0' is negative"]
    tables, inventory = ingest_run(run.run_dir)
    assert len(tables["ranges"]) == 39                      # 40 lines, one negative range
    assert inventory["rss.csv"]["quarantined"] == 2           # the -inf RSSI, counted by the ingest
    assert references.published_values(run.run_dir) == {"LS RMSE": 1.5, "LS RMSE_2d": 1.25}
    ls = references.published_tracks(run.run_dir)["LS"]
    # LS is (3 + 0.2 k, 5) at t = 1 + 0.5 k; truth (0.1 (t - 1) / 0.125, 1): errors sqrt((3 - 0.6 k)^2 + 16)
    k = np.arange(4)
    expected = np.sqrt(np.mean((3 + 0.2 * k - 0.4 * k) ** 2 + 16))
    assert references.rmse_of(ls, tables["truth"]) == pytest.approx(expected, rel=1e-9)


def test_weighted_centroid_uses_the_three_strongest_per_second():
    anchors = pd.DataFrame({"anchor_id": ["a", "b", "c", "d"], "x": [0.0, 6.0, 0.0, 50.0], "y": [0.0, 0.0, 6.0, 50.0]})
    rss = pd.DataFrame({"t": [0.1, 0.2, 0.3, 0.4], "anchor_id": ["a", "b", "c", "d"],
                        "rss_dbm": [-60.0, -60.0, -60.0, -90.0]})
    out = references.weighted_centroid(rss, anchors)
    assert out[["x", "y"]].to_numpy()[0].tolist() == pytest.approx([2.0, 2.0]) and out["t"].iloc[0] == pytest.approx(0.6)


def test_path_loss_ekf_finds_a_static_beacon_from_exact_rss():
    anchors = pd.DataFrame({"anchor_id": list("abcd"), "x": [0.0, 10.0, 0.0, 10.0], "y": [0.0, 0.0, 10.0, 10.0],
                            "z": [2.3, 1.2, 2.3, 1.2]})
    model = {"p0_dbm": -60.0, "path_loss_exponent": 2.0, "sigma_db": 2.0, "d0_m": 1.0}
    beacon, t = np.array([3.0, 6.0]), np.arange(0.0, 60.0, 0.05)
    ids = np.array(list("abcd"))[np.arange(len(t)) % 4]
    xyz = anchors.set_index("anchor_id").loc[ids]
    d = np.sqrt((xyz["x"].to_numpy() - beacon[0]) ** 2 + (xyz["y"].to_numpy() - beacon[1]) ** 2
                + (xyz["z"].to_numpy() - 1.8) ** 2)
    rss = pd.DataFrame({"t": t, "anchor_id": ids, "rss_dbm": -60.0 - 20.0 * np.log10(d)})
    out = references.path_loss_ekf(rss, anchors, model, 1.8)
    assert np.hypot(out["x"].iloc[-1] - 3.0, out["y"].iloc[-1] - 6.0) < 0.05


def _range_run(scale):
    anchors = pd.DataFrame({"anchor_id": ["A", "B", "C", "D"], "tech": "uwb", "x": [0.0, 20.0, 0.0, 20.0],
                            "y": [0.0, 0.0, 20.0, 20.0], "z": np.nan})
    t = np.arange(0.0, 60.0, 0.1)
    path = np.column_stack([2 + 0.25 * t, 5 + 0.15 * t])
    ids = anchors["anchor_id"].to_numpy()[np.arange(len(t)) % 4]
    xy = anchors.set_index("anchor_id").loc[ids, ["x", "y"]].to_numpy()
    ranges = pd.DataFrame({"t": t, "anchor_id": ids, "range_m": scale * np.hypot(*(path - xy).T), "status": 0})
    truth = pd.DataFrame({"t": t, "x": path[:, 0], "y": path[:, 1]})
    return RunData({"anchors": anchors, "ranges": ranges, "truth": truth}), truth


def test_diagnosis_names_a_range_scale_error_and_its_remedy():
    data, truth = _range_run(1.07)
    estimates = truth.assign(nis=1.0, n_meas=1)
    estimates.attrs = {"gated_share": 0.0, "resets": 0}
    d = diagnose_run(data, estimates, {"update": "sequential", "range_sigma_m": 0.3, "range_calibration": "none"})
    assert d["range_scale"] == pytest.approx(1.07, abs=1e-6)
    assert "range_scale" not in diagnose_run(data, estimates, registry.get("minmax").resolve({}))   # no calibration to take
    tracker = registry.get("tracker").resolve({})
    assert any("ranges look 7% long" in f and "range_self_calibration=scale" in f for f in findings(d, tracker))
    # advice names only settings the estimator has: multilateration has no range_self_calibration
    said = [f for f in findings(d, registry.get("multilateration").resolve({})) if "ranges look 7% long" in f]
    assert len(said) == 1 and "range_self_calibration" not in said[0] and "--calibration DONOR_RUN" in said[0]
    poor = dict(d, gated_share=0.31)                     # against a track the gate disagreed with: a caveat
    assert any("ranges look 7% long against the track (read against a track whose gate rejected 31%" in f
               for f in findings(poor, {}))
    fitted = dict(d, self_fit_range_correction="applied", calibrated_scale=1.07)      # the self-fit's output pass
    assert any("ranges look 7% long" in f and "the self-fit corrected it (scale 1.070 applied)" in f
               for f in findings(fitted, {}))
    apart = dict(fitted, calibrated_scale=1.005)        # the self-fit read another scale: the track's own error
    assert any("ranges look 7% long" in f and "more likely the track's own error" in f and "found and applied 1.005"
               in f and "corrected it" not in f for f in findings(apart, {}))
    biased = dict(fitted, range_offsets_m={"A": 0.3, "B": 0.0}, calibrated_offsets_m={"A": 0.29, "B": 0.01})
    assert any("A +0.30 m" in f and "the self-fit corrected them" in f for f in findings(biased, {}))
    other = dict(biased, calibrated_offsets_m={"A": 0.02, "B": -0.01})     # left by the outliers and the track
    assert any("A +0.30 m" in f and "applied its own correction" in f and "(calibrated_offsets_m: A +0.02 m, B -0.01 m)"
               in f and "the self-fit corrected them" not in f for f in findings(other, {}))
    scale_only = dict(biased, self_fit_range_correction="applied, scale only (offsets not constant)")
    assert any("A +0.30 m" in f and "left them out" in f and "--calibration DONOR_RUN" in f
               for f in findings(scale_only, {}))
    clean, _ = _range_run(1.0)
    assert findings(diagnose_run(clean, estimates, {"update": "sequential", "range_calibration": "none"}), {}) == []
    donor = RunData(data.tables, None, None, "donor-calibrated", {"scale": 1.07, "offsets_m": {}})   # as the filter read them
    assert "range_scale" in diagnose_run(donor, estimates, {"update": "sequential", "range_calibration": "other_run"})
    assert findings(diagnose_run(donor, estimates, {"update": "sequential", "range_calibration": "other_run"}), {}) == []


def test_diagnosis_flags_gate_restarts_and_a_nis_above_its_band():
    data, truth = _range_run(1.0)
    estimates = truth.assign(nis=4.0, n_meas=1)
    estimates.attrs = {"gated_share": 0.4, "resets": 3}
    d = diagnose_run(data, estimates, {"update": "sequential"})
    text = " ".join(findings(d, {"range_sigma_m": 0.1}))
    assert "rejected 40%" in text and "restarted 3 time(s)" in text and "range_sigma_m about 0.2" in text
    particles = " ".join(findings(d, registry.get("pf").resolve({})))      # no gate: outliers raise its NIS
    assert "particle filter updates with every measurement" in particles and "range_sigma_m about" not in particles
    assert "gate lost" not in particles and "came from one anchor for longer than max_coast_s" in particles
    window = " ".join(findings(d, registry.get("sliding_window").resolve({})))
    assert "gate lost" not in window and "a window's solution was dropped" in window
    assert "the gate lost the track" in " ".join(findings(d, registry.get("tracker").resolve({})))


def test_diagnosis_names_the_gaps_behind_the_restarts():
    data, truth = _range_run(1.0)
    ranges = data.table("ranges")
    gapped = RunData(dict(data.tables, ranges=ranges[(ranges["t"] < 20.0) | (ranges["t"] > 35.0)]))
    estimates = truth.assign(nis=1.0, n_meas=1)
    estimates.attrs = {"gated_share": 0.0, "resets": 1}
    tracker = registry.get("tracker").resolve({})
    d = diagnose_run(gapped, estimates, dict(tracker, update="sequential"))
    (start, end, anchor), = d["gaps"]
    assert (start, end) == pytest.approx((19.9, 35.1), abs=0.05) and anchor is None and metrics_of(d)["diag_gaps"] == 1
    said = " ".join(findings(d, tracker))
    assert "the measurements stop for longer than max_coast_s (10.0 s) 1 time(s) (20-35 s after the first " \
        "measurement): no estimate there is expected" in said and "gate lost" not in said
    assert "restarted 1 time(s): 1 time(s) the gate lost the track" in " ".join(findings(dict(d, gaps=[]), tracker))
    both = " ".join(findings(dict(d, restarts=3), tracker))            # one gap, two losses
    assert "1 time(s) (20-35 s" in both and "the other 2 time(s) the gate lost the track" in both


def _self_fitted(nis: float, gated: float, run: float, core: float, **process) -> tuple:
    """(data, estimates, diagnose_run) of a self-fitted run: NIS `nis` per update, the gated share,
    the self-fit's run sigma, the innovations' core sigma and its fitted process noise (attrs
    self_fit_<key>, as bayes.run_filter writes them); the range correction not supported."""
    data, truth = _range_run(1.0)
    estimates = truth.assign(nis=nis, n_meas=1)
    estimates.attrs = {"gated_share": gated, "resets": 0, "self_fit_run_sigma_m": run, "self_fit_range_sigma_m": core,
                       **{f"self_fit_{k}": v for k, v in process.items()}, "self_fit_range_correction": "not supported"}
    return data, estimates, diagnose_run(data, estimates, {"update": "sequential"})


def test_diagnosis_explains_the_nis_of_a_self_fitted_run():
    """The self-fit runs a wider sigma than the innovations' core on purpose: a NIS below its band then
    names both sigmas and why the core's sigma is not the setting to take (it gates NLOS-long ranges out:
    cucudasluv nlos/a-case-2 RMSE 0.73 -> 1.86 m that way), instead of 'noise set too large'."""
    _, _, d = _self_fitted(0.2, 0.0, 0.15, 0.07, accel_sigma_mps2=0.7)
    text = " ".join(findings(d, {"range_sigma_m": 0.3}))
    assert "self-fit ran with range sigma 0.15 m" in text and "core is about 0.07 m" in text
    assert "pessimistic by about 2.2x" in text and "(0.07 m, accel_sigma_mps2 0.7)" in text
    assert "not a setting to change" in text
    assert "range correction not supported" in report(d, {"range_sigma_m": 0.3})
    assert metrics_of(d)["diag_self_fit_range_corrected"] == 0.0


def test_a_nis_below_its_band_with_a_core_wider_than_the_run_sigma_is_read_as_the_gates_truncation():
    """Where the innovations' core is not narrower than the run's sigma (simulated newcom/variable:
    core 0.85 m, run 0.6 m, NIS 0.18, 10% gated) the NIS is low because it counts only the kept
    measurements: the diagnosis says so instead of calling the covariance pessimistic by design."""
    _, _, d = _self_fitted(0.18, 0.1, 0.6, 0.85, accel_sigma_mps2=0.24)
    text = " ".join(findings(d, {"range_sigma_m": 0.3}))
    assert "counts only the measurements the gate kept (10% gated)" in text
    assert "pessimistic" not in text and "larger than the data need" not in text


def test_diagnosis_of_a_self_fitted_p_model_names_its_process_noise():
    """ekf_p self-fits p_sigma_m (its random walk), not accel_sigma_mps2: the diagnosis keeps that key
    and its advice for a NIS below the band names p_sigma_m with the fitted value."""
    data, estimates, d = _self_fitted(0.2, 0.0, 0.15, 0.07, p_sigma_m=0.4)
    assert d["self_fit_p_sigma_m"] == 0.4
    text = " ".join(findings(d, {"range_sigma_m": 0.3, "motion": "p"}))
    assert "(0.07 m, p_sigma_m 0.4)" in text and "accel" not in text
    estimates = estimates.assign(nis=40.0)
    assert "process noise (p_sigma_m)" in " ".join(findings(diagnose_run(data, estimates, {}), {"motion": "p"}))


def test_rss_only_runs_are_estimated_on_their_rss():
    anchors = pd.DataFrame({"anchor_id": ["a"], "tech": "ble", "x": [0.0], "y": [0.0], "z": [np.nan]})
    rss = pd.DataFrame({"t": [0.0], "anchor_id": ["a"], "rss_dbm": [-60.0]})
    data = RunData({"anchors": anchors, "rss": rss})
    assert measurements_for(data, {"measurements": "toa", "fixes": "toa"}, set()) == {"measurements": "rss",
                                                                                      "fixes": "rss"}
    assert measurements_for(data, {"measurements": "toa"}, {"measurements"}) == {"measurements": "toa"}
    # an estimator that reads ranges only (sliding_window) is told so, before any donor calibration
    # (it reached the RSS model fit and stopped with KeyError 'path_loss_exponent')
    with pytest.raises(ConfigError, match="reads measurements toa / tdoa only"):
        measurements_for(data, {"measurements": "toa"}, set(), {"measurements": ("toa", "tdoa")})


def _ble_run(root, seed=0):
    anchors = [("s1", 0.0, 0.0), ("s2", 12.0, 0.0), ("s3", 0.0, 12.0), ("s4", 12.0, 12.0)]
    root.mkdir(parents=True)
    (root / "anchors.csv").write_text("anchor_id,tech,x,y,z\n" + "".join(f"{a},ble,{x},{y},2.0\n" for a, x, y in anchors))
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 60.0, 0.1)
    path = np.column_stack([3 + 0.1 * t, 4 + 0.05 * t])
    rows = []
    for k, tk in enumerate(t):
        a, x, y = anchors[k % 4]
        d = np.sqrt((path[k, 0] - x) ** 2 + (path[k, 1] - y) ** 2 + 0.04)
        rows.append(f"{tk:.2f},{a},{-55 - 25 * np.log10(d) + rng.normal(0, 2):.1f}\n")
    (root / "rss.csv").write_text("t,anchor_id,rss_dbm\n" + "".join(rows) + "60.0,s9,-70\n60.1,s1,nan\n")
    (root / "truth.csv").write_text("t,x,y\n" + "".join(f"{a:.2f},{x},{y}\n" for a, (x, y) in zip(t, path)))
    (root / "meta.yaml").write_text("tag_height_m: 1.8\n")


def test_estimate_with_no_flags_on_rss_only_reports_quarantine_and_diagnosis(tmp_path, capsys):
    _ble_run(tmp_path / "run")
    _ble_run(tmp_path / "donor", seed=1)
    assert main(["estimate", "--format", "generic", str(tmp_path / "run"), "--out", str(tmp_path / "est")]) == 0
    out = capsys.readouterr().out
    assert "measurements=rss" in out and "2 row(s) quarantined" in out and "unknown anchor" in out
    # 0.5 s outputs over 60 s; on RSS alone the track starts after one full 4 s initiator window
    assert "diagnosis:" in out and "112 estimates" in out
    assert main(["estimate", "--format", "generic", str(tmp_path / "run"), "--out", str(tmp_path / "cal"),
                 "--calibration", str(tmp_path / "donor")]) == 0
    metrics = json.loads((tmp_path / "cal" / "metrics.json").read_text())
    assert metrics["rss_model"].startswith("fitted on") and metrics["median_m"] < 3.0


def test_calibration_alone_calibrates_the_ranges(tmp_path, capsys):
    for name in ("run", "donor"):
        root = tmp_path / name
        root.mkdir()
        data, truth = _range_run(1.07)
        data.table("anchors").drop(columns="z").to_csv(root / "anchors.csv", index=False)
        data.table("ranges").drop(columns="status").to_csv(root / "ranges.csv", index=False)
        truth.to_csv(root / "truth.csv", index=False)
    assert main(["estimate", "--format", "generic", str(tmp_path / "run"), "--out", str(tmp_path / "est"),
                 "--calibration", str(tmp_path / "donor")]) == 0
    metrics = json.loads((tmp_path / "est" / "metrics.json").read_text())
    assert metrics["range_calibration"].startswith("fitted on") and metrics["calibrated_scale"] == pytest.approx(1.07)


def test_estimate_exits_non_zero_past_the_quarantine_limits(tmp_path, capsys):
    _ble_run(tmp_path / "run")
    text = (tmp_path / "run" / "rss.csv").read_text().splitlines()
    (tmp_path / "run" / "rss.csv").write_text("\n".join(text[:1] + [line.replace(",s1,", ",zz,") for line in text[1:]])
                                              + "\n")
    assert main(["estimate", "--format", "generic", str(tmp_path / "run"), "--out", str(tmp_path / "est")]) == 2
    assert "quarantine" in capsys.readouterr().err


def test_datasets_without_their_source_are_skipped_with_their_study_scenarios(tmp_path):
    config = {"datasets": {"real": {"convert": {"dataset": "philotuxo", "source": str(tmp_path / "absent")}},
                           "sim": {}},
              "studies": {"a": {"scenarios": ["real/tracks"]}, "b": {"scenarios": ["real/tracks", "sim/x"],
                                                                       "overrides": {"real": {}, "sim": {}}}}}
    messages = without_missing_sources(config)
    assert len(messages) == 1 and "'real' skipped" in messages[0]
    assert list(config["datasets"]) == ["sim"] and list(config["studies"]) == ["b"]
    assert config["studies"]["b"] == {"scenarios": ["sim/x"], "overrides": {"sim": {}}}


def test_quarantine_notes_show_the_offending_values_cut_to_a_readable_width():
    from wsnloc.metrics.data_quality import quarantine_by_reason

    long = "x" * 60
    quarantine = pd.DataFrame({"file": ["ranges.csv"] * 4 + ["rss.csv"],
                               "reason": ["range_m '-1.5' is negative", "range_m '-0.2' is negative",
                                          "range_m '-1.5' is negative", f"range_m '{long}' is not a number",
                                          "unknown anchor 'A9' (not in anchors.csv)"]})
    notes = {(file, reason): n for file, reason, n in quarantine_by_reason(quarantine)}
    assert notes[("ranges.csv", "range_m '…' is negative (e.g. '-1.5', '-0.2')")] == 3
    assert notes[("ranges.csv", f"range_m '{long[:23]}…' is not a number")] == 1
    assert notes[("rss.csv", "unknown anchor 'A9' (not in anchors.csv)")] == 1


def test_a_donor_exponent_candidate_without_a_score_cannot_win_and_is_named():
    """donor_rss_model: a candidate whose estimates do not meet the donor's truth has no RMSE (NaN); it
    used to lose every comparison silently (the prior kept, nothing said). Now it is 'not scored' in the
    text, and the other candidate wins."""
    from synthetic import RSS_MODEL, SQUARE, tables_for, walk
    from wsnloc.campaign import Campaign
    from wsnloc.experiments.calibration import donor_rss_model

    times = np.arange(0.5, 60.0, 0.5)
    tables = tables_for(times, np.array(["A1"] * len(times), dtype=object), walk, SQUARE, rss_times=times)
    site = Campaign(name="generic", format="generic", spec={}, source="(test)")
    truth = tables["truth"]

    def track(model):           # the prior's estimates lie after the donor's truth: no RMSE
        shift = 1000.0 if model["path_loss_exponent"] == 2.0 else 0.0
        return truth.iloc[::10][["t", "x", "y"]].assign(t=lambda f: f["t"] + shift)

    model = donor_rss_model(tables["rss"], truth, site, RSS_MODEL["d0_m"], 2.0, track, tables["anchors"])
    assert model["exponent_source"] == "donor fit"
    assert "prior n=2.00: not scored" in model["exponent_choice"]
