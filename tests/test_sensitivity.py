"""Sensitivity grid, set-up facts and "why it differs" sentences on inputs with known answers."""

import math

import numpy as np
import pandas as pd
import pytest

from wsnloc import results
from wsnloc.analysis import setup_facts
from wsnloc.errors import ConfigError
from wsnloc.experiments import paper_b, sensitivity
from wsnloc.experiments.paper_b import report as paper_b_report
from wsnloc.metrics.verdicts import DOES_NOT_HOLD, HOLDS
from wsnloc.report import explanations
from wsnloc.report.sections import grid_table, paper_section, sensitivity_table

SPEC = {"parameters": {"fix_sigma_m": 1.0, "accel_sigma_mps2": 0.3},
        "estimators": {"kalman": {"estimator": "kf_tracker", "accel_sigma_mps2": 0.5}, "fused": {"estimator": "dr_kf"}},
        "sensitivity": {"runs": 2, "factors": [0.5, 2.0],
                        "sigmas": ["fix_sigma_m", "kalman.accel_sigma_mps2", "fused.fix_sigma_m"]}}


def test_variants_scale_one_sigma_at_a_time_and_leave_the_config_alone():
    """A shared key is scaled in `parameters`; `cell.parameter` in that cell's entry, from its own
    value or else the shared one it inherits."""
    from wsnloc.experiments import cells

    grid = sensitivity.variants(SPEC, "experiments.paper_x")
    assert [label for label, _, _ in grid] == ["fix_sigma_m x0.5", "fix_sigma_m x2", "kalman.accel_sigma_mps2 x0.5",
                                               "kalman.accel_sigma_mps2 x2", "fused.fix_sigma_m x0.5",
                                               "fused.fix_sigma_m x2"]
    scaled = {label: spec for label, _, spec in grid}
    assert scaled["fix_sigma_m x2"]["parameters"]["fix_sigma_m"] == 2.0
    assert scaled["fix_sigma_m x2"]["estimators"]["kalman"]["accel_sigma_mps2"] == 0.5
    assert scaled["kalman.accel_sigma_mps2 x0.5"]["estimators"]["kalman"]["accel_sigma_mps2"] == 0.25
    assert scaled["kalman.accel_sigma_mps2 x0.5"]["parameters"]["accel_sigma_mps2"] == 0.3
    assert scaled["fused.fix_sigma_m x0.5"]["estimators"]["fused"] == {"estimator": "dr_kf", "fix_sigma_m": 0.5}
    assert SPEC["parameters"]["fix_sigma_m"] == 1.0 and SPEC["estimators"]["kalman"]["accel_sigma_mps2"] == 0.5
    assert sensitivity.variants({**SPEC, "sensitivity": {"runs": 0, "sigmas": ["fix_sigma_m"]}}, "x") == []
    # the cells each sigma acts on: a shared key every cell whose estimator has it, a cell's own key that cell
    assert cells.acted_on(SPEC, "fix_sigma_m") == ["fused"]
    assert cells.acted_on(SPEC, "accel_sigma_mps2") == []          # kalman sets its own
    assert cells.acted_on(SPEC, "kalman.accel_sigma_mps2") == ["kalman"]


def test_unknown_sigma_names_the_config_key():
    for sigma in ("kalman.nope", "nope", "other.fix_sigma_m"):
        bad = {**SPEC, "sensitivity": {**SPEC["sensitivity"], "sigmas": ["fix_sigma_m", sigma]}}
        with pytest.raises(ConfigError, match=r"experiments.paper_x.sensitivity.sigmas.1"):
            sensitivity.variants(bad, "experiments.paper_x")


def _paper_b_metrics(runs, fusion_gain):
    rows = []
    for i, run in enumerate(runs):
        level = 1.0 + 0.3 * i
        for method, value in (("uwb", level), ("imu", level + 1.0), ("sskf", level - fusion_gain),
                              ("kf", level - fusion_gain - 0.01 * (1 + 0.1 * i))):
            rows.append({"method": method, "rmse": value, "run": run})
    return pd.DataFrame(rows)


def test_grid_reruns_only_the_sampled_runs_and_decides_each_setting():
    runs = [f"run-{i:02d}" for i in range(1, 6)]
    metrics = _paper_b_metrics(runs, 0.2)
    calls = []

    def evaluate(spec, sigma, run):
        calls.append((sigma, run))
        # a large fix sigma makes the fusion worse than UWB only in this constructed case
        gain = 0.2 if spec["parameters"]["fix_sigma_m"] <= 1.0 else -0.2
        rerun = _paper_b_metrics(runs, gain)
        rerun = rerun[(rerun["run"] == run) & rerun["method"].isin(["sskf", "kf"])].drop(columns="run")
        return sensitivity.replace_cells(metrics, run, rerun, ["method"])

    spec = {"parameters": {"fix_sigma_m": 1.0},
            "sensitivity": {"runs": 3, "factors": [0.5, 2.0], "sigmas": ["fix_sigma_m"]}}
    grid = sensitivity.grid_metrics(spec, "experiments.paper_b", metrics, sensitivity.each_run(evaluate))
    assert sorted(set(run for _, run in calls)) == runs[:3] and len(calls) == 6
    assert set(grid["setting"]) == {"x1", "fix_sigma_m x0.5", "fix_sigma_m x2"}
    assert len(grid[grid["setting"] == "fix_sigma_m x2"]) == 3 * 4     # 3 runs x 4 methods, no duplicates
    rows = results.frame(sensitivity.results_rows("B", {"x/s": grid}, paper_b.claims))
    fusion = rows[rows["row"] == "Fusion beats both UWB only and IMU only"].set_index("column")["value"]
    assert fusion.to_dict() == {"x1": 1, "fix_sigma_m x0.5": 1, "fix_sigma_m x2": -1}
    claims = [{"claim": "Fusion beats both UWB only and IMU only", "verdict": HOLDS}]
    table = sensitivity_table(rows, "B", claims, sensitivity.TABLE)
    assert table["settings"][0] == "x1"
    assert table["rows"][0]["cells"] == [HOLDS, HOLDS, DOES_NOT_HOLD] and not table["rows"][0]["robust"]
    # the UWB ranging levels (nlos_sweep) are a table of their own: the report shows two narrower tables
    from wsnloc.analysis.nlos_severity import CLAIMS_TABLE

    levels = results.frame(sensitivity.results_rows("B", {"x/s": grid.assign(setting=grid["setting"].map(
        {"x1": "spec", "fix_sigma_m x0.5": "harsh", "fix_sigma_m x2": "harsher"}))}, paper_b.claims, CLAIMS_TABLE))
    both = pd.concat([rows, levels], ignore_index=True)
    assert sensitivity_table(both, "B", claims, sensitivity.TABLE)["settings"] == table["settings"]
    ranging = sensitivity_table(both, "B", claims, CLAIMS_TABLE)
    assert ranging["settings"] == ["spec", "harsh", "harsher"] and ranging["rows"][0]["cells"] == table["rows"][0]["cells"]


def test_static_share_and_measurements_per_epoch():
    t = np.arange(0, 10, 0.5)
    x = np.where(t < 2.5, 0.0, 0.3 * (t - 2.5))          # still for the first 2.5 s, then 0.3 m/s
    cell = pd.DataFrame({"run": "run-01", "t": t, "true_x": x, "true_y": 0.0, "n_meas": np.arange(len(t)) % 3})
    # speeds: epochs 1..5 still (first takes the second's speed), then moving
    assert setup_facts.static_share(cell).loc["run-01"] == pytest.approx(6 / len(t))
    assert setup_facts.measurements_per_epoch(cell).loc["run-01"] == pytest.approx(np.mean(np.arange(len(t)) % 3))


def test_paper_a_setup_counts_the_measurements_its_filters_used_and_says_so():
    """Paper A's Set-up rows are the mean n_meas of Table I's first TOA and RSS rows per epoch, and
    their labels say so (the logs' anchors per round are another count: pl0_sensitivity)."""
    from wsnloc.experiments import paper_a

    from wsnloc.experiments.paper_a import report as paper_a_report

    spec = {"rows": [{"measurements": "toa", "anchors": "UWB=12"}, {"measurements": "toa", "anchors": "UWB=9"},
                     {"measurements": "rss", "anchors": "ZigBee=21"}, {"measurements": "rss", "anchors": "ZigBee=17"}]}
    t = np.arange(0.0, 5.0, 0.5)
    est = pd.concat([pd.DataFrame({"table": "Table I", "row": paper_a.row_label(row), "run": "run-01", "t": t,
                                   "true_x": 0.3 * t, "true_y": 0.0, "n_meas": n})
                     for row, n in zip(spec["rows"], (9.0, 7.0, 17.0, 14.0))], ignore_index=True)
    frame = results.frame(paper_a.setup_rows({"newcom/constant": est}, spec))
    facts = frame.set_index("row")["value"]
    toa, rss = paper_a.MEASUREMENTS_USED["toa"], paper_a.MEASUREMENTS_USED["rss"]
    assert facts[toa] == 9.0 and facts[rss] == 17.0
    assert all("used per epoch" in label for label in paper_a.MEASUREMENTS_USED.values())
    # per anchor subset: each row's own count, quoted for the cells of that subset only
    assert facts[f"{toa} (UWB=9)"] == 7.0 and facts[f"{rss} (ZigBee=17)"] == 14.0 and facts[f"{toa} (UWB=12)"] == 9.0
    numbers = explanations.Numbers(frame, {})
    fewer = explanations.cell_mechanism(numbers, "A", "newcom/constant", "Table I", "hybrid | UWB=9, ZigBee=17", "c")
    assert f"{toa} (UWB=9) 7.0" in fewer and f"{rss} (ZigBee=17) 14.0" in fewer and "9.0" not in fewer
    rss_only = explanations.cell_mechanism(numbers, "A", "newcom/constant", "Table I", "RSS (ZigBee) | ZigBee=21", "c")
    assert f"{rss} (ZigBee=21) 17.0" in rss_only and "UWB" not in rss_only and "14.0" not in rss_only
    config = {"datasets": {"newcom": {"campaign": "config/campaigns/newcom.yaml"}}}
    [line] = [line for line in paper_a_report.why(numbers, config, ["newcom/constant"], spec, 0.5) if "per 0.5 s" in line]
    assert ("9.0 UWB ranges with UWB=12, 7.0 UWB ranges with UWB=9, 17.0 ZigBee RSS values with ZigBee=21, "
            "14.0 ZigBee RSS values with ZigBee=17") in line


def test_explanations_cite_the_computed_numbers_and_skip_missing_ones():
    rows = [setup_facts.fact_row("B", "static share of epochs", "d/s", pd.Series([0.1, 0.2]), "share"),
            results.row_over_runs([0.8, 0.9], experiment="B", table="RMSE", row=paper_b.METHODS["uwb"], column="d/s",
                                  scenario="d/s", metric="rmse_m", paper_value=3.25)]
    summaries = {"d/s": {"range_error_pooled": {"LOS": {"n": 60, "median": 0.05},
                                                "NLOS": {"n": 40, "bias": 0.5, "p95": 1.1}}}}
    numbers = explanations.Numbers(results.frame(rows), summaries)
    text = paper_b_report.why(numbers, ["d/s"], [])
    assert any("0.85 m against the paper's 3.25 m: 40% of our UWB ranges are NLOS" in line for line in text)
    assert any("stands still 15% of the time" in line for line in text)
    # no NLOS links: the ranging sentence is left out, not written with "nan"
    no_nlos = explanations.Numbers(results.frame(rows), {"d/s": {"range_error_pooled": {"LOS": {"n": 10}}}})
    assert all("nan" not in line and "NLOS" not in line for line in paper_b_report.why(no_nlos, ["d/s"], []))
    assert math.isnan(numbers.value("B", "RMSE", "missing", "d/s"))


def test_paper_c_noise_curves_follow_each_models_own_sigma():
    from wsnloc.experiments import paper_c

    spec = {"table_1_subset": "6", "table_2_subsets": ["6"], "table_2_scenario": "c/s",
            "sensitivity": {"sigmas": ["P.p_sigma_m", "PV.accel_sigma_mps2", "PVA.accel_sigma_mps2"]}}
    rows = []
    for setting, sigma, factor in (("x1", None, 1.0), ("PV.accel_sigma_mps2 x2", "PV.accel_sigma_mps2", 2.0),
                                   ("P.p_sigma_m x2", "P.p_sigma_m", 2.0)):
        for model in paper_c.MODELS:
            own = sigma is not None and sigma.startswith(f"{model}.")
            for run, noise in (("run-01", -0.01), ("run-02", 0.01)):
                rows.append({"subset": "6", "model": model, "rmse": 0.2 * (factor if own else 1.0) + noise,
                             "run": run, "setting": setting, "sigma": sigma, "factor": factor})
    curves = paper_c.noise_curves(pd.DataFrame(rows), spec)     # sigma None as read back from CSV
    assert curves["PV (accel_sigma_mps2)"]["x"].tolist() == [1.0, 2.0]
    assert curves["PV (accel_sigma_mps2)"]["value"].tolist() == pytest.approx([0.2, 0.4])
    assert curves["P (p_sigma_m)"]["value"].tolist() == pytest.approx([0.2, 0.4])
    assert "PVA (accel_sigma_mps2)" not in curves       # its sigma was not scaled: one point only


def test_static_share_sweep_lengthens_the_rest_and_pairs_the_runs(campaign):
    from wsnloc.analysis import static_share
    from wsnloc.experiments import paper_a

    from test_ekf import SPEC_A

    spec = {**SPEC_A, "parameters": {**SPEC_A["parameters"], "rss_calibration": "other_run_common"},
            "rows": [{"measurements": "toa", "anchors": "UWB=12"}, {"measurements": "hybrid", "anchors": "UWB=12+ZigBee=21"}]}
    sweep = static_share.gain_against_rest(campaign, "constant", [5.0, 30.0], 2, 11, spec)
    assert list(sweep["run"]) == ["run-01", "run-02"] * 2
    share = sweep.groupby("rest_s")["static_share"].mean()
    constant = campaign.section("scenarios", "constant")
    assert share[30.0] > share[5.0] + 0.15 and campaign.section("scenarios", "constant") == constant   # copy only
    assert np.allclose(sweep["gain_m"], sweep["rmse_detection_m"] - sweep["rmse_plain_m"])
    rows = results.frame(paper_a.static_sweep_rows(sweep, "newcom/constant"))
    assert set(rows["column"]) == {"final rest 5 s", "final rest 30 s"} and (rows["runs"] == 2).all()
    curve = paper_a.static_sweep_curve(sweep)
    assert curve["x"].tolist() == pytest.approx(sorted(share.tolist()))


def test_nlos_severity_sweep_adds_the_configured_excess_per_wall(campaign):
    """A level's radio.uwb value reaches the simulated ranges; its label says what it is."""
    from wsnloc.analysis import nlos_severity
    from wsnloc.analysis.simulated_runs import with_value
    from wsnloc.metrics.ranging import range_errors

    with pytest.raises(KeyError, match="radio.uwb.no_such_key"):
        with_value(campaign, ("radio", "uwb", "no_such_key"), 1.0)

    def nlos_excess(severe, tables):
        rows = []
        for name, t in tables.items():
            errors = range_errors(t["ranges"], t["truth"], severe)
            nlos = errors[errors["walls"] > 0]
            rows.append({"run": name, "per_wall_m": float(np.median(nlos["error_m"] / nlos["walls"]))})
        return pd.DataFrame(rows)

    levels = {"spec": {}, "severe": {"excess_path_per_wall_m": 2.3}}
    sweep = nlos_severity.sweep(campaign, "constant", levels, 1, 5, nlos_excess)
    by_setting = sweep.set_index("setting")["per_wall_m"]
    assert list(by_setting.index) == ["DW1000-class (spec) (1 simulated run)",
                                      "DW1000-class (spec), NLOS excess 2.3 m/wall (1 simulated run)"]
    low, high = by_setting.iloc[0], by_setting.iloc[1]
    # same seeds: the channel part of each NLOS range is shared, the wall part grows by 2 m per wall
    assert high - low == pytest.approx(2.0, abs=0.05)
    assert campaign.section("radio", "uwb")["excess_path_per_wall_m"] == 0.3


def test_a_level_without_changes_reuses_the_workflows_runs(campaign, tmp_path, monkeypatch):
    """The workflow's simulate + ingest of runs 1..N give the tables the sweep would simulate
    (same campaign, seeds and reader), so the {} level reads them and only the other levels
    simulate."""
    from wsnloc.analysis import nlos_severity, simulated_runs
    from wsnloc.io.ingest import ingest_scenario
    from wsnloc.io.limits import QuarantineLimits
    from wsnloc.metrics.data_quality import load_runs
    from wsnloc.sim.newcom import simulate_run
    from wsnloc.sim.seeding import run_seed_sequence

    raw = {"run-01": simulate_run(campaign, "constant", run_seed_sequence(5, "newcom", "constant", 1),
                                  tmp_path / "raw" / "run-01")}
    ingest_scenario("newcom", raw, campaign, tmp_path / "tables", QuarantineLimits(), tmp_path / "keep")
    workflow_runs = load_runs(tmp_path / "tables")
    simulated = simulated_runs.simulate_tables(campaign, "constant", 1, 5)
    for name in ("ranges", "rss", "imu", "truth"):
        pd.testing.assert_frame_equal(workflow_runs["run-01"][name], simulated["run-01"][name], check_dtype=False,
                                      check_like=True)   # Parquet: schema types and column order

    calls = []
    original = nlos_severity.simulate_tables
    monkeypatch.setattr(nlos_severity, "simulate_tables", lambda c, *a: calls.append(c) or original(c, *a))
    levels = {"spec": {}, "severe": {"excess_path_per_wall_m": 2.3}}
    count = lambda severe, tables: pd.DataFrame({"run": list(tables), "n": [len(t["ranges"]) for t in tables.values()]})
    sweep = nlos_severity.sweep(campaign, "constant", levels, 1, 5, count, simulated=workflow_runs)
    assert len(calls) == 1 and calls[0].section("radio", "uwb")["excess_path_per_wall_m"] == 2.3
    assert sweep["n"].iloc[0] == len(workflow_runs["run-01"]["ranges"])


def test_nlos_levels_apply_the_hardware_class_then_the_level_values(campaign):
    from wsnloc.analysis import nlos_severity
    from wsnloc.errors import ConfigError

    era = nlos_severity.level_campaign(campaign, {"hardware_class": "ieee802154a_2009", "timing_noise_ns": 2.0}, "x.era")
    uwb, spec_class = era.section("radio", "uwb"), campaign.section("radio", "uwb")
    era_class = spec_class["hardware_classes"]["ieee802154a_2009"]
    assert uwb["cir_tap_ns"] == era_class["cir_tap_ns"] and uwb["timing_noise_ns"] == 2.0
    assert uwb["excess_path_per_wall_m"] == spec_class["excess_path_per_wall_m"]     # not in the class: kept
    assert nlos_severity.setting_label(era, {"hardware_class": "ieee802154a_2009", "timing_noise_ns": 2.0}, 2) \
        == f"{era_class['hardware_label']}, timing noise 2 ns (2 simulated runs)"
    with pytest.raises(ConfigError, match=r"config key 'x\.era\.hardware_class': no hardware class 'dw3000'"):
        nlos_severity.level_campaign(campaign, {"hardware_class": "dw3000"}, "x.era")


def test_ranging_severity_rows_and_sentence_carry_the_computed_rmse():
    from wsnloc.analysis import nlos_severity
    from wsnloc.report import explanations

    severity = pd.DataFrame({"method": ["uwb", "imu"] * 4, "rmse": [0.8, 2.0, 1.0, 2.0, 3.0, 2.0, 3.4, 2.0],
                             "run": ["r1", "r1", "r2", "r2"] * 2, "setting": ["spec"] * 4 + ["era"] * 4})
    rows = nlos_severity.rmse_rows("B", "newcom/constant", severity)
    frame = results.frame(rows).set_index(["row", "column"])
    assert frame.loc[("uwb", "spec"), "value"] == pytest.approx(0.9) and frame.loc[("uwb", "era"), "runs"] == 2
    assert frame.loc[("uwb", "era"), "value"] == pytest.approx(3.2)
    numbers = explanations.Numbers(results.frame(rows), {})
    [line] = explanations.ranging_severity(numbers, "B", {"Min-Max on UWB": "uwb"}, "; paper: 3.25 m")
    assert "newcom/constant" in line and "spec: Min-Max on UWB 0.90 m; era: Min-Max on UWB 3.20 m; paper: 3.25 m" in line
    assert explanations.ranging_severity(numbers, "D", {"Min-Max UWB": "minmax/uwb/raw"}, "") == []


def test_a_sigma_set_per_scenario_is_scaled_where_the_overrides_set_it():
    """Paper C's P sigma is set per speed (overrides): its sensitivity variants scale those values."""
    from wsnloc.experiments.sensitivity import variants

    spec = {"estimators": {"P": {"estimator": "ekf", "motion": "p"}},
            "overrides": {"c/s20": {"P": {"p_sigma_m": 0.1}}, "c/s40": {"P": {"p_sigma_m": 0.2}}},
            "sensitivity": {"runs": 2, "factors": [0.5, 2.0], "sigmas": ["P.p_sigma_m"]}}
    (_, _, half), (_, _, double) = variants(spec, "experiments.paper_c")
    assert [half["overrides"][k]["P"]["p_sigma_m"] for k in ("c/s20", "c/s40")] == [0.05, 0.1]
    assert [double["overrides"][k]["P"]["p_sigma_m"] for k in ("c/s20", "c/s40")] == [0.2, 0.4]
    assert "p_sigma_m" not in half["estimators"]["P"] and spec["overrides"]["c/s20"]["P"]["p_sigma_m"] == 0.1


def test_every_cell_outside_our_interval_gets_a_computed_mechanism():
    methods = [paper_b.METHODS["uwb"], paper_b.METHODS["imu"]]
    rows = [results.row_over_runs([0.8, 0.9, 0.85] * 4, experiment="B", table="RMSE", row=methods[0], column="d/s",
                                  scenario="d/s", metric="rmse_m", paper_value=3.25),          # outside
            results.row_over_runs([20.0, 30.0, 25.0] * 4, experiment="B", table="RMSE", row=methods[1], column="d/s",
                                  scenario="d/s", metric="rmse_m", paper_value=25.0),          # inside
            setup_facts.fact_row("B", "static share of epochs", "d/s", pd.Series([0.01, 0.02]), "share")]
    summaries = {"d/s": {"range_error_pooled": {"LOS": {"n": 60, "median": 0.05},
                                                "NLOS": {"n": 40, "bias": 0.5, "p95": 1.1}}}}
    frame = results.frame(rows)
    numbers = explanations.Numbers(frame, summaries)
    table = grid_table(frame, experiment="B", table="RMSE", rows=methods, columns=["d/s"], metric="rmse_m",
                       title="RMSE [m]")
    section = paper_section("B", {"title": "t", "citation": "c"}, {}, {"claims": []}, {}, numbers=numbers,
                            tables=[table], why=["a paper sentence"])
    outside = explanations.outside_cells(section["tables"])
    assert [row["label"] for _, row, _, _ in outside] == [methods[0]]
    for _, row, column, cell in outside:
        line = next(line for line in section["why"] if line.startswith(f"RMSE [m], {row['label']} / {column}:"))
        assert f"ours {cell['value']:.3f}" in line and "paper's 3.250" in line
        assert "40% of the ranges are NLOS (median excess 0.50 m" in line and "static share of epochs 2%" in line
        # below the paper: our NLOS bias raises ours, so it is not counted; the paper's ranging need is
        assert "NLOS bias sqrt" not in line and f"3.250 / 0.850 = {3.25 / 0.85:.2f} times less accurate" in line
    assert section["why"][0] == "a paper sentence" and len(section["why"]) == 2   # none for the inside cell
    # the mechanism follows the data: other numbers, other sentence
    other = explanations.Numbers(frame, {"d/s": {"range_error_pooled": {"LOS": {"n": 90, "median": 0.02},
                                                                         "NLOS": {"n": 10, "bias": 0.2}}}})
    assert "10% of the ranges are NLOS (median excess 0.20 m" in explanations.cell_whys(other, "B", [table])[0]
    # the kind of cell chooses the mechanism: dead reckoning gets the rest share, not the ranging
    imu = explanations.cell_mechanism(numbers, "B", "d/s", "RMSE [m]", methods[1], "d/s")
    assert "no rest to measure the IMU biases in" in imu and "NLOS" not in imu


NUMBER = r"([+-]?[0-9]+(?:\.[0-9]+)?)"


def check_gap_account(line: str, ours: float, paper: float) -> list[str]:
    """Re-do the arithmetic of one cell sentence's account of the gap from the numbers it prints;
    returns the names of the contributions it found. Tolerances: the printed rounding."""
    import re

    found, predicted = [], []
    for x, b, c in re.findall(rf"sqrt\(x b\^2\) = sqrt\({NUMBER} x {NUMBER}\^2\) = {NUMBER} m", line):
        assert float(c) == pytest.approx(math.sqrt(float(x)) * float(b), abs=2e-3)
        found.append("nlos")
        predicted.append(float(c))
    for value, moving, c in re.findall(rf"moving-epoch RMSE = {NUMBER} - {NUMBER} = {NUMBER} m", line):
        assert float(c) == pytest.approx(float(value) - float(moving), abs=1.5e-3)
        found.append("rests")
        predicted.append(float(c))
    for sigma, duration, c in re.findall(rf"\|b\| = sqrt\(2\) x {NUMBER} m/s\^2, T = {NUMBER} s: {NUMBER} m", line):
        assert float(c) == pytest.approx(math.sqrt(2) * float(sigma) * float(duration) ** 2 / (2 * math.sqrt(5)),
                                         rel=2e-3, abs=2e-3)
        found.append("drift")
        predicted.append(float(c))
    [(total, gap, rest)] = re.findall(rf"predicted {NUMBER} m against the gap {NUMBER} m: {NUMBER} m unexplained", line)
    assert float(gap) == pytest.approx(ours - paper, abs=1.5e-3)
    assert float(total) == pytest.approx(sum(predicted), abs=1.5e-3 * len(predicted))
    assert float(rest) == pytest.approx(float(gap) - float(total), abs=1.5e-3)
    return found


def test_the_gap_account_is_computed_from_the_builds_numbers_and_its_arithmetic_holds():
    """An RMSE cell outside the interval: NLOS bias sqrt(x) b, the rests (RMSE - moving RMSE) and,
    for dead reckoning without a rest, the bias drift |b| T^2 / (2 sqrt 5) are predicted; their sum
    is set against the gap and the rest is called unexplained. Other numbers, other account."""
    rows = [results.row_over_runs([0.9, 1.0, 0.95] * 4, experiment="A", table="Table I", row="distance (UWB)",
                                  column="constant", scenario="newcom/constant", metric="rmse_m", paper_value=0.46),
            results.row_over_runs([0.8, 0.9, 0.85] * 4, experiment="A", table="Table I detail", row="distance (UWB)",
                                  column="rmse_moving", scenario="newcom/constant", metric="rmse_moving_m"),
            results.row_over_runs([20.0, 30.0, 25.0] * 4, experiment="B", table="RMSE", row=paper_b.METHODS["imu"],
                                  column="newcom/b_real", scenario="newcom/b_real", metric="rmse_m", paper_value=1.22),
            setup_facts.fact_row("B", "static share of epochs", "newcom/b_real", pd.Series([0.0, 0.0]), "share")]
    summaries = {"newcom/constant": {"range_error_pooled": {"LOS": {"n": 64, "median": 0.05},
                                                            "NLOS": {"n": 36, "bias": 1.25}}},
                 "newcom/b_real": {"per_run": [{"duration_s": 60.0}, {"duration_s": 62.0}]}}
    config = {"datasets": {"newcom": {"campaign": "config/campaigns/newcom.yaml"}}}
    frame = results.frame(rows)
    numbers = explanations.Numbers(frame, summaries, config)
    table_a = grid_table(frame, experiment="A", table="Table I", rows=["distance (UWB)"], columns=["constant"],
                         metric="rmse_m", title="Table I: RMSE [m] (plain EKF)")
    [line] = explanations.cell_whys(numbers, "A", [table_a])
    assert check_gap_account(line, 0.95, 0.46) == ["nlos", "rests"]
    assert "sqrt(0.360 x 1.250^2) = +0.750 m" in line and "0.950 - 0.850 = +0.100 m" in line
    assert "predicted +0.850 m against the gap +0.490 m: -0.360 m unexplained" in line
    # dead reckoning on a scenario without rests, the campaign's accelerometer bias (mems model)
    table_b = grid_table(frame, experiment="B", table="RMSE", rows=[paper_b.METHODS["imu"]], columns=["newcom/b_real"],
                         metric="rmse_m", title="RMSE [m]")
    [line] = explanations.cell_whys(numbers, "B", [table_b])
    assert check_gap_account(line, 25.0, 1.22) == ["drift"]
    sigma = explanations.campaign_of(config, "newcom/b_real").section("imu", "accel_bias_sigma_mps2")
    assert f"T = 61.0 s: {math.sqrt(2) * sigma * 61.0**2 / (2 * math.sqrt(5)):+.3f} m" in line
    # paper B's simulation scenario has no accelerometer bias (snr model): no drift, no rest missed
    assert numbers.imu_bias_sigma("newcom/b_simulation", "accel_bias_sigma_mps2") == 0.0
    # paper B's "why it differs" quotes the campaign's IMU biases, not numbers of its own
    gyro = explanations.campaign_of(config, "newcom/b_real").section("imu", "gyro_bias_sigma_dps")
    [drift] = [line for line in paper_b_report.why(numbers, ["newcom/b_real"], []) if "turn-on bias" in line]
    assert f"({sigma:g} m/s^2 per axis, 1 sigma, campaign)" in drift and f"gyro bias ({gyro:g} deg/s)" in drift
    assert f"b T^2 / 2 ({0.5 * sigma * 61.0**2:.0f} m over the 61 s run)" in drift
    assert math.isnan(numbers.imu_bias_sigma("x/y", "accel_bias_sigma_mps2"))
    simulation = explanations.Numbers(results.frame([
        results.row_over_runs([1.5, 1.6, 1.55] * 4, experiment="B", table="RMSE", row=paper_b.METHODS["imu"],
                              column="newcom/b_simulation", scenario="newcom/b_simulation", metric="rmse_m",
                              paper_value=1.42),
        setup_facts.fact_row("B", "static share of epochs", "newcom/b_simulation", pd.Series([0.0, 0.0]), "share")]),
        {"newcom/b_simulation": {"per_run": [{"duration_s": 60.0}]}}, config)
    [line] = explanations.cell_whys(simulation, "B", [grid_table(
        simulation.results, experiment="B", table="RMSE", rows=[paper_b.METHODS["imu"]],
        columns=["newcom/b_simulation"], metric="rmse_m", title="RMSE [m]")])
    assert "static share of epochs 0%" in line and "no rest to measure" not in line
    assert "No mechanism quantified for this cell: the gap +0.130 m" in line
    # without the mechanisms' numbers: the gap is stated as not accounted for, not explained away
    bare = explanations.Numbers(frame, {}, None)
    [line] = explanations.cell_whys(bare, "B", [table_b])
    assert "No mechanism quantified for this cell: the gap +23.780 m is not accounted for" in line
    # a run with rests whose dead reckoning measures no bias in them (BIAS_CALIBRATION 0 s) drifts
    # as one without rests; a calibration at rest removes the term
    for calibration, drifts in ((0.0, True), (5.0, False)):
        rested = explanations.Numbers(results.frame(rows[:3] + [
            setup_facts.fact_row("B", "static share of epochs", "newcom/b_real", pd.Series([0.1, 0.1]), "share"),
            setup_facts.fact_row("B", setup_facts.BIAS_CALIBRATION, "newcom/b_real",
                                 pd.Series([calibration] * 2), "seconds")]), summaries, config)
        [line] = explanations.cell_whys(rested, "B", [table_b])
        assert ("T = 61.0 s: " in line and "the biases are not measured" in line) is drifts
        assert ("No mechanism quantified" in line) is not drifts
    # a max error of dead reckoning without a rest: the bias drift at the run's end, |b| T^2 / 2
    [line] = explanations.cell_whys(numbers, "B", [dict(table_b, title="Max error [m]")])
    assert f"T = 61.0 s: {math.sqrt(2) * sigma * 61.0**2 / 2:+.3f} m" in line and "No mechanism quantified" not in line
    # no account for cells that are neither RMSE nor max errors
    [line] = explanations.cell_whys(numbers, "B", [dict(table_b, title="Availability")])
    assert "ours 25.000" in line and "Account of the gap" not in line and "No mechanism quantified" not in line


def test_rss_cells_get_the_wall_losses_relative_range_error():
    """An RSS cell above the paper: eps = ln(10) sigma / (10 n) over all links against LOS links,
    RMSE (1 - eps_LOS / eps_all); other fits, other term; none without the LOS fit."""
    rows = [results.row_over_runs([0.9, 1.1, 1.0] * 4, experiment="A", table="Table I", row="RSS (ZigBee) | ZigBee=21",
                                  column="constant", scenario="d/s", metric="rmse_m", paper_value=0.691)]
    frame = results.frame(rows)
    table = grid_table(frame, experiment="A", table="Table I", rows=["RSS (ZigBee) | ZigBee=21"], columns=["constant"],
                       metric="rmse_m", title="Table I: RMSE [m] (plain EKF)", scenario="d/s")
    run = {"fit_all_n": 3.0, "fit_all_sigma_dB": 6.0, "fit_los_n": 3.0, "fit_los_sigma_dB": 4.5}
    [line] = explanations.cell_whys(explanations.Numbers(frame, {"d/s": {"per_run": [run]}}), "A", [table])
    eps_all, eps_los = math.log(10) * 6.0 / 30.0, math.log(10) * 4.5 / 30.0
    assert f"= {eps_all:.3f} over all links" in line and f"against {eps_los:.3f} on LOS links" in line
    assert f"RMSE x (1 - {eps_los:.3f} / {eps_all:.3f}) = {1.0 * (1 - 4.5 / 6.0):+.3f} m" in line
    assert f"against the gap {1.0 - 0.691:+.3f} m: {1.0 - 0.691 - 0.25:+.3f} m unexplained" in line
    [line] = explanations.cell_whys(explanations.Numbers(frame, {"d/s": {"per_run": [dict(run, fit_los_sigma_dB=6.0)]}}),
                                    "A", [table])
    assert "RMSE x (1 - 0.461 / 0.461) = +0.000 m" in line
    [line] = explanations.cell_whys(explanations.Numbers(frame, {"d/s": {"per_run": [dict(run, fit_los_n=None)]}}),
                                    "A", [table])
    assert "No mechanism quantified" in line


def test_below_the_paper_only_terms_that_lower_ours_count_and_the_ranging_need_is_computed():
    """A range-based cell below the paper: our NLOS term (it raises ours) is left out of the sum;
    a term of the paper (paper_terms) is counted; the rest is what the paper's ranging needs,
    k = (paper + explained) / ours, sqrt(k^2 - 1) x our median range error."""
    rows = [results.row_over_runs([0.19, 0.21, 0.20] * 4, experiment="C", table="Table I", row="PVA", column="20 cm/s",
                                  scenario="c/s", metric="rmse_m", paper_value=0.5)]
    frame = results.frame(rows)
    summaries = {"c/s": {"range_error_pooled": {"LOS": {"n": 90, "median": 0.02}, "NLOS": {"n": 10, "bias": 0.3}}}}
    numbers = explanations.Numbers(frame, summaries)
    table = grid_table(frame, experiment="C", table="Table I", rows=["PVA"], columns=["20 cm/s"], metric="rmse_m",
                       title="Table I: RMSE [m], beacons 6", scenario="c/s")
    [line] = explanations.cell_whys(numbers, "C", [table])
    assert "NLOS bias sqrt" not in line and "no computed term lowers ours: the gap -0.300 m is unexplained" in line
    k = 0.5 / 0.2
    assert f"{k:.2f} times less accurate ranges" in line and f"= {math.sqrt(k * k - 1) * 0.02:.3f} m (median)" in line
    [line] = explanations.cell_whys(numbers, "C", [table], lambda *_: [("model part", -0.1)])
    assert "model part; predicted -0.100 m against the gap -0.300 m: -0.200 m unexplained" in line
    assert f"0.400 / 0.200 = {0.4 / 0.2:.2f} times" in line
    # above the paper the same NLOS term counts
    [line] = explanations.cell_whys(numbers, "C", [dict(table, rows=[dict(table["rows"][0], cells=[
        dict(table["rows"][0]["cells"][0], paper=0.1, delta=0.1)])])])
    assert f"= {math.sqrt(0.1) * 0.3:+.3f} m; predicted" in line and "less accurate ranges" not in line


def test_a_fused_cell_without_rests_gets_the_drift_of_the_counterfactual_without_bias():
    """Paper B's fusion on a scenario with a biased IMU and no rest: ours minus the same row on the
    scenario whose IMU has no bias (b_simulation), in place of the NLOS term."""
    method = paper_b.METHODS["sskf"]
    rows = [results.row_over_runs([6.0, 8.0, 7.0] * 4, experiment="B", table="RMSE", row=method,
                                  column="newcom/b_real", scenario="newcom/b_real", metric="rmse_m", paper_value=0.88),
            results.row_over_runs([0.6, 0.7, 0.65] * 4, experiment="B", table="RMSE", row=method,
                                  column="newcom/b_simulation", scenario="newcom/b_simulation", metric="rmse_m",
                                  paper_value=0.62),
            setup_facts.fact_row("B", "static share of epochs", "newcom/b_real", pd.Series([0.0, 0.0]), "share")]
    frame = results.frame(rows)
    config = {"datasets": {"newcom": {"campaign": "config/campaigns/newcom.yaml"}}}
    summaries = {"newcom/b_real": {"range_error_pooled": {"LOS": {"n": 60, "median": 0.05},
                                                          "NLOS": {"n": 40, "bias": 1.2}}}}
    table = grid_table(frame, experiment="B", table="RMSE", rows=[method], columns=["newcom/b_simulation", "newcom/b_real"],
                       metric="rmse_m", title="RMSE [m]")
    [line] = [line for line in explanations.cell_whys(explanations.Numbers(frame, summaries, config), "B", [table])
              if "b_real:" in line]
    assert "gives 0.650 m): 7.000 - 0.650 = +6.350 m; predicted +6.350 m against the gap +6.120 m" in line
    assert "NLOS bias sqrt" not in line.split("Account of the gap")[1]


def test_paper_terms_of_papers_b_and_c_carry_their_arithmetic():
    """Paper C: a model's own part (ours_M - ours_P) - (paper_M - paper_P) and the acceleration
    2 dp / T^2 it needs; paper B: the era of UWB ranging from the severity sweep (negative, below
    the paper) and the SNR at which our curve meets the paper's value."""
    from wsnloc.analysis.nlos_severity import TABLE
    from wsnloc.experiments.paper_c import report as paper_c_report

    rows = [results.row_over_runs([v] * 3, experiment="C", table="Table I", row=m, column="20 cm/s", scenario="c/s",
                                  metric="rmse_m", paper_value=p) for m, v, p in (("P", 0.2, 0.35), ("PVA", 0.25, 0.5))]
    numbers = explanations.Numbers(results.frame(rows), {})
    [(text, value)] = paper_c_report.model_part(numbers, "Table I", "PVA", "20 cm/s", 0.5, 0.3, 1.0, 9.80665)
    assert value == pytest.approx(0.05 - 0.15) and "+0.050 - (+0.150) = -0.100 m" in text
    leak = 9.80665 * math.sin(math.radians(1.0))
    assert f"a = 2 x 0.150 / 0.5^2 = {0.3 / 0.25:.2f} m/s^2" in text and f"{1.2 / leak:.1f} times the tilt" in text
    assert paper_c_report.model_part(numbers, "Table I", "P", "20 cm/s", 0.5, 0.3, 1.0, 9.80665) == []
    rows = [results.row_over_runs([v] * 2, experiment="B", table=TABLE, row="uwb", column=level, scenario="d/s",
                                  metric="rmse_m") for level, v in (("spec", 1.4), ("era", 1.6))]
    rows += [results.row_over_runs([v] * 2, experiment="B", table=paper_b.SNR_TABLE, row=paper_b.METHODS["imu"],
                                   column=f"{snr} dB", scenario="d/sim", metric="rmse_m")
             for snr, v in ((50, 2.6), (60, 1.5), (70, 1.3))]
    numbers = explanations.Numbers(results.frame(rows), {})
    [(text, value)] = paper_b_report.paper_terms(numbers, paper_b.METHODS["uwb"], "d/s",
                                                 {"scenario": "d/s", "delta": -1.9, "paper": 3.25})
    assert value == pytest.approx(-0.2) and "1.400 - 1.600 = -0.200 m" in text
    assert paper_b_report.paper_terms(numbers, paper_b.METHODS["uwb"], "d/s",
                                      {"scenario": "d/s", "delta": 0.5, "paper": 1.0}) == []
    [(text, value)] = paper_b_report.paper_terms(numbers, paper_b.METHODS["imu"], "60 dB",
                                                 {"scenario": "d/sim", "delta": 0.08, "paper": 1.42})
    meet = 60 + 10 * (1.5 - 1.42) / (1.5 - 1.3)
    assert value is None and f"= {meet:.1f} dB" in text and f"= {10 ** (-(meet - 60) / 20):.2f} times" in text


def test_the_papers_per_scenario_calibration_refuses_other_run():
    """rss_models_for_runs fits one P0, n, sigma on the next run (other_run_common); `other_run` (per-receiver
    P0s, exponent chosen by tracking the donor) was silently fitted the same way: now refused, naming the key."""
    from wsnloc.errors import ConfigError
    from wsnloc.experiments import calibration

    p = {"rss_calibration": "other_run", "p0_dbm": -50.0, "path_loss_exponent": 2.0, "sigma_db": 4.0, "d0_m": 1.0}
    with pytest.raises(ConfigError, match="'rss_calibration': other_run .* use other_run_common"):
        calibration.rss_models_for_runs({"a": {}, "b": {}}, None, [], p)
