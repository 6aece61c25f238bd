"""Claims decided on per-run metrics: paired and Welch intervals against scipy, run alignment,
results rows, and papers' claims on per-run tables whose answer is known by construction."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from wsnloc import results
from wsnloc.experiments import claims, paper_c, paper_d
from wsnloc.metrics import op_counts
from wsnloc.metrics.verdicts import DOES_NOT_HOLD, HOLDS, INCONCLUSIVE
from wsnloc.report.sections import cell_of, summary

RUNS = [f"run-{i:02d}" for i in range(1, 21)]


def test_unpaired_interval_is_welchs_from_scipy():
    rng = np.random.default_rng(1)
    a, b = rng.normal(0.40, 0.05, 12), rng.normal(0.55, 0.15, 20)
    result = claims.unpaired(a, b, "<", "a - b")
    expected = stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert (result.ci95_low, result.ci95_high) == pytest.approx((expected.low, expected.high))
    assert result.mean_diff == pytest.approx(a.mean() - b.mean()) and result.runs == 12
    assert result.verdict == HOLDS and claims.unpaired(a, b, ">", "a - b").verdict == DOES_NOT_HOLD
    assert claims.unpaired(a[:1], b, "<", "one run").verdict == INCONCLUSIVE


def test_paired_aligns_runs_by_name_and_drops_unmatched():
    a = pd.Series([1.0, 2.0, 3.0, 9.0], index=["run-01", "run-02", "run-03", "run-09"])
    b = pd.Series([2.5, 1.1, 2.1], index=["run-03", "run-01", "run-02"])     # other order, run-09 missing
    result = claims.paired(a, b, "<", "a - b")
    assert result.runs == 3 and result.mean_diff == pytest.approx(np.mean([-0.1, -0.1, 0.5]))


def test_results_rows_give_the_verdict_code_and_every_comparison():
    part = claims.paired(pd.Series([1.0, 1.1, 0.9], index=RUNS[:3]), pd.Series([2.0, 2.2, 1.9], index=RUNS[:3]),
                         "<", "x - y")
    from wsnloc.metrics.verdicts import claim
    rec = claims.record("x beats y", claim([part]))
    assert rec["verdict"] == HOLDS and "x - y < 0? -1.033 m" in rec["evidence"]
    rows = results.frame(claims.results_rows("Z", [rec, claims.decided_record("fixed", False, "counted")]))
    verdict_rows = rows[rows["metric"] == "verdict"]
    assert verdict_rows["value"].tolist() == [1, -1] and verdict_rows["column"].tolist() == [HOLDS, DOES_NOT_HOLD]
    part_row = rows[rows["table"] == claims.PARTS_TABLE].iloc[0]
    assert (part_row["value"], part_row["ci95_low"], part_row["runs"]) == (part.mean_diff, part.ci95_low, 3)



def test_write_outputs_appends_the_claim_rows_and_writes_the_verdicts(tmp_path):
    import json

    decided = [claims.decided_record("fixed", True, "counted")]
    table_row = {"experiment": "Z", "table": "Table I", "row": "x", "column": "c", "scenario": "d/s",
                 "metric": "rmse_m", "value": 0.5, "ci95_low": 0.4, "ci95_high": 0.6, "runs": 3, "paper_value": None}
    claims.write_outputs("Z", [table_row], decided, tmp_path / "results.csv", tmp_path / "claims.json")
    written = results.read(tmp_path / "results.csv")
    assert written["table"].tolist()[0] == "Table I" and (written["metric"] == "verdict").sum() == 1
    assert json.loads((tmp_path / "claims.json").read_text()) == {"claims": decided}

def _paper_d_metrics(rng, minmax_offset):
    """Per-run RMSE of every paper D cell: a per-run common level (what pairing removes) plus
    a cell offset; Min-Max sits `minmax_offset` m from multilateration."""
    level = rng.normal(1.0, 0.3, len(RUNS))
    technique = {"narrowband": 0.6, "uwb": 0.3, "pmix": 0.2, "fmix": 0.1}
    stage = {"raw": 0.0, "velocity": -0.05, "kalman": -0.08}
    rows = []
    for loc, loc_offset in (("minmax", minmax_offset), ("multilateration", 0.0)):
        for t, t_offset in technique.items():
            for s, s_offset in stage.items():
                values = level + loc_offset + t_offset + s_offset + rng.normal(0, 0.005, len(RUNS))
                rows += [{"localizer": loc, "technique": t, "stage": s, "rmse": v, "run": r}
                         for v, r in zip(values, RUNS)]
    return pd.DataFrame(rows)


def test_paper_d_claims_follow_the_constructed_ordering():
    rng = np.random.default_rng(7)
    decided = {c["claim"]: c["verdict"] for c in paper_d.claims({"x/better": _paper_d_metrics(rng, -0.1)})}
    assert decided["Fusion beats a single source"] == HOLDS
    assert decided["F-mix is the best fusion and technique"] == HOLDS
    assert decided["Velocity tracking lowers the RMSE in every cell"] == HOLDS
    assert decided["F-mix followed by velocity tracking gives the lowest RMSE"] == HOLDS
    assert decided["Min-Max is more accurate than multilateration"] == HOLDS
    assert decided["The Kalman filter is slightly more accurate than the velocity tracker (within 25%)"] == HOLDS
    worse = {c["claim"]: c["verdict"] for c in paper_d.claims({"x/worse": _paper_d_metrics(rng, +0.1)})}
    assert worse["Min-Max is more accurate than multilateration"] == DOES_NOT_HOLD
    equal = {c["claim"]: c["verdict"] for c in paper_d.claims({"x/equal": _paper_d_metrics(rng, 0.0)})}
    assert equal["Min-Max is more accurate than multilateration"] == INCONCLUSIVE


def test_paper_d_cost_claim_is_decided_on_operation_counts():
    counts = op_counts.cost_table(window=6)
    rec = paper_d.cost_claim(counts, {"velocity tracker": 12.0, "Kalman filter": 72.0})
    ratio = op_counts.kalman_step().total / op_counts.velocity_tracker_step(6).total
    assert rec["verdict"] == (HOLDS if ratio > 2 else DOES_NOT_HOLD) and f"ratio {ratio:.1f}" in rec["evidence"]
    rows = results.frame(paper_d.operation_rows(counts, {"velocity tracker": 12.0, "Kalman filter": 72.0}))
    total = rows[(rows["row"] == "Kalman filter") & (rows["column"] == "total per step")]["value"].iloc[0]
    assert total == op_counts.kalman_step().total
    assert rows[rows["metric"] == "ratio"]["paper_value"].iloc[0] == pytest.approx(6.0)


def test_paper_c_speed_claim_compares_independent_scenarios():
    rng = np.random.default_rng(3)
    layout = {"table_1_subset": "6", "table_2_subsets": ["3", "6"], "table_2_scenario": "c/s20"}

    def scenario(level):
        frame = pd.DataFrame([{"subset": subset, "model": m, "rmse": level + 0.05 * k + extra + rng.normal(0, 0.01),
                               "run": r} for subset, extra in (("6", 0.0), ("3", 0.1))
                              for k, m in enumerate(paper_c.MODELS) for r in RUNS])
        # rests at the ends lower the overall RMSE of the slow scenario most: only moving epochs decide speed
        return frame.assign(rmse_moving=frame["rmse"], rmse=frame["rmse"] - 2 * level + 1.0)

    metrics = {"c/s20": scenario(0.3), "c/s40": scenario(0.4), "c/s60": scenario(0.5)}
    speeds = {"c/s20": "20 cm/s", "c/s40": "40 cm/s", "c/s60": "60 cm/s"}
    decided = {c["claim"]: c for c in paper_c.claims(metrics, speeds, layout)}
    assert [decided[k]["verdict"] for k in decided] == [HOLDS, HOLDS, HOLDS]
    assert "moving epochs (independent runs)" in decided["The error grows with speed (every model)"]["evidence"]


def test_cells_show_the_difference_only_where_the_paper_lies_outside_our_interval():
    res = results.frame([
        results.row_over_runs([0.40, 0.41, 0.42, 0.43, 0.44], experiment="A", table="T", row="r", column="in", scenario="s",
                              metric="rmse_m", paper_value=0.43),
        results.row_over_runs([0.40, 0.41, 0.42, 0.43, 0.44], experiment="A", table="T", row="r", column="out", scenario="s",
                              metric="rmse_m", paper_value=0.60),
        results.row_over_runs([0.40, 0.41, 0.42, 0.43, 0.44], experiment="A", table="T", row="r", column="none", scenario="s",
                              metric="rmse_m")])
    inside, outside, none = (cell_of(res, column=c) for c in ("in", "out", "none"))
    assert inside["inside"] and inside["delta"] is None
    assert not outside["inside"] and outside["delta"] == pytest.approx(0.42 - 0.60)
    assert none["paper"] is None and none["delta"] is None and not none["inside"]
    section = {"id": "A", "title": "t", "tables": [{"rows": [{"cells": [inside, outside, none]}]}],
               "claims": [{"verdict": HOLDS}, {"verdict": INCONCLUSIVE}, {"verdict": INCONCLUSIVE}]}
    assert summary([section]) == [{"id": "A", "title": "t", "cells": 2, "inside": 1, "claims": 3,
                                   "verdicts": {HOLDS: 1, DOES_NOT_HOLD: 0, INCONCLUSIVE: 2}}]


def _runs_by_mask(metrics: pd.DataFrame, metric: str = "rmse", **keys) -> pd.Series:
    """The former runs_of: a boolean mask per call (the reference for the indexed look-up)."""
    match = np.ones(len(metrics), dtype=bool)
    for column, value in keys.items():
        match &= metrics[column].to_numpy() == value
    sel = metrics[match]
    return pd.Series(sel[metric].to_numpy(float), index=sel["run"].to_numpy(), name=metric)


def test_runs_of_matches_a_boolean_mask_in_row_order_with_missing_keys():
    rng = np.random.default_rng(3)
    n = 60
    metrics = pd.DataFrame({"loc": rng.choice(["minmax", "multilateration", None], n),
                            "tech": rng.choice(["uwb", "fmix"], n), "stage": rng.choice(["raw", "velocity"], n),
                            "run": rng.permutation([f"run-{i:02d}" for i in range(n)]), "rmse": rng.random(n)})
    metrics = metrics.astype({"loc": "str", "tech": "str", "stage": "str", "run": "str"})
    keys = [{"loc": loc, "tech": tech, "stage": stage} for loc in ("minmax", "multilateration", "absent")
            for tech in ("uwb", "fmix") for stage in ("raw", "velocity")] + [{"tech": "uwb"}, {}]
    for _ in range(2):     # the second pass reads the index built by the first
        for key in keys:
            pd.testing.assert_series_equal(claims.runs_of(metrics, **key), _runs_by_mask(metrics, **key))
    shuffled = metrics.iloc[::-1].reset_index(drop=True)     # another frame, not the first one's index
    pd.testing.assert_series_equal(claims.runs_of(shuffled, tech="uwb"), _runs_by_mask(shuffled, tech="uwb"))


def test_report_cell_is_the_first_matching_row():
    frame = results.frame([results.single_row(v, experiment="D", table="T", row=r, column="c", scenario="s",
                                              metric="rmse_m", paper_value=1.0)
                           for v, r in ((0.5, "a"), (0.7, "b"), (0.9, "a"))])
    assert cell_of(frame, row="a", column="c")["value"] == 0.5 and cell_of(frame, row="b")["value"] == 0.7
    assert cell_of(frame, row="z")["value"] is None


def test_report_numbers_read_the_first_matching_row_or_nan():
    from wsnloc.report.explanations import Numbers
    rows = [results.single_row(v, experiment="A", table="T", row=r, column="c", scenario=s, metric="rmse_m")
            for v, r, s in ((0.5, "a", "x"), (0.7, "a", "y"), (None, "b", "x"), (0.9, "a", "x"))]
    numbers = Numbers(results.frame(rows), {})
    assert numbers.value("A", "T", "a", "c") == 0.5 and numbers.value("A", "T", "a", "c", scenario="y") == 0.7
    assert np.isnan(numbers.value("A", "T", "b", "c")) and np.isnan(numbers.value("A", "T", "z", "c"))


def test_one_published_run_is_compared_with_the_per_run_band_a_mean_with_the_mean_interval():
    """Issue 29 item 4: a single run of the paper lies inside the 2.5-97.5 percentiles of our per-run
    values although outside our mean's 95% interval; a published mean is held to the mean's interval."""
    per_run = np.linspace(0.30, 0.60, 20)                     # mean 0.45, its interval about +-0.05
    one_run = results.row_over_runs(per_run, experiment="A", table="T", row="r", column="run", scenario="s",
                                    metric="rmse_m", paper_value=0.33)
    mean = results.row_over_runs(per_run, experiment="A", table="T", row="r", column="mean", scenario="s",
                                 metric="rmse_m", paper_value=0.33, paper_is_mean=True)
    assert (one_run["band_low"], one_run["band_high"]) == pytest.approx(tuple(np.percentile(per_run, [2.5, 97.5])))
    assert mean["band_low"] is None and one_run["ci95_low"] > 0.33            # outside the mean's interval
    res = results.frame([one_run, mean])
    run_cell, mean_cell = cell_of(res, column="run"), cell_of(res, column="mean")
    assert run_cell["basis"] == "run" and run_cell["inside"] and run_cell["delta"] is None
    assert mean_cell["basis"] == "mean" and not mean_cell["inside"] and mean_cell["delta"] == pytest.approx(0.45 - 0.33)
    too_few = results.row_over_runs(per_run[:4], experiment="A", table="T", row="r", column="few", scenario="s",
                                    metric="rmse_m", paper_value=0.33)
    assert too_few["band_low"] is None                                         # no band from 4 runs
