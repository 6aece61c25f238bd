"""Snakemake adapter: paper B estimators on every run of each of its scenarios, then the paper's
tables, claims and figures over all scenarios (read back from the scenarios' files)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from pathlib import Path

import pandas as pd

from wsnloc.analysis import imu_snr, nlos_severity
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import cells, claims as claims_of, paper_b, sensitivity, why
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.report import figures
from wsnloc.sim import imu as sim_imu
from wsnloc.workflow import each_scenario, read_scenario_files

spec = sm.params.spec


def run_scenario(label: str, campaign: Campaign, out: dict) -> None:
    """Every run of one scenario: estimates, per-run metrics and sensitivity grid written to
    out['estimates'], out['metrics'], out['sensitivity']."""
    estimates, metrics, data = [], [], {}
    runs = load_runs(sm.params.sources["tables_of"][label], paper_b.INPUT_TABLES, sm.params.sources["imu_of"][label])
    for name, run_tables in runs.items():
        data[name] = RunData(run_tables, campaign, None, name)
        est = paper_b.run(data[name], spec, label).assign(run=name)
        estimates.append(est)
        metrics.append(paper_b.run_metrics(est, run_tables["truth"]).assign(run=name))
    tables.write("estimates_paper_b", pd.concat(estimates, ignore_index=True), out["estimates"])
    metrics = pd.concat(metrics, ignore_index=True)
    metrics.to_csv(out["metrics"], index=False, float_format="%.6g")

    def fusion_variant(variant: dict, sigma: str, run: str) -> pd.DataFrame:
        """Re-run the methods the scaled sigma acts on (cells.acted_on: the fusions), keep the run's others."""
        fused = paper_b.run(data[run], variant, label, [m for m in paper_b.METHODS if m in cells.acted_on(variant, sigma)])
        return sensitivity.replace_cells(metrics, run, paper_b.run_metrics(fused, runs[run]["truth"]), ["method"])

    grid = sensitivity.grid_metrics(spec, cells.where(paper_b.PAPER), metrics, sensitivity.each_run(fusion_variant))
    grid.to_csv(out["sensitivity"], index=False, float_format="%.6g")
    log.info("%s: %d runs done", label, len(runs))


def summarize() -> None:
    """Tables (results.csv), claims and figures of paper B over all its scenarios, from the
    files run_scenario wrote (metrics as written, to 6 significant digits), with the opt-in
    SNR curve and NLOS-severity sweep."""
    paper = read_yaml(sm.input.papers)["B"]
    labels, simulated = list(sm.params.sources["labels"]), set(sm.params.simulated)
    files = read_scenario_files(sm.output, labels)
    per_run, grids, estimates = files["metrics"], files["sensitivity"], files["estimates"]
    rows = [row for label in labels for row in paper_b.results_rows(per_run[label], label, paper, label in simulated)]
    campaigns = {path: Campaign.load(path) for path in set(sm.params.sources["campaign_of"].values())}
    decided = why.explain_b(paper_b.claims(per_run), per_run,
                            {label: cells.params(spec, "imu", label, "paper_b")["static_start_s"] for label in labels},
                            {label: sim_imu.bias_sigma(campaigns[sm.params.sources["campaign_of"][label]],
                                                   label.split("/", 1)[1], sim_imu.ACCEL_BIAS) for label in labels})
    curve = None
    if sm.params.snr_curve["runs"] and sm.params.snr_scenario:
        dataset, scenario = sm.params.snr_scenario.split("/", 1)
        curve = imu_snr.rmse_against_snr(Campaign.load(sm.input.snr_campaign[0]), scenario,
                                          sm.params.snr_curve["snrs_db"], sm.params.snr_curve["runs"], sm.params.seed,
                                          sm.params.resample,
                                          cells.params(spec, "imu", sm.params.snr_scenario, paper_b.PAPER)["static_start_s"],
                                          dataset)
        rows += paper_b.snr_rows(curve, sm.params.snr_scenario, paper)
    nlos = spec.get("nlos_sweep") or {"runs": 0}   # claims against NLOS ranging severity (opt-in)
    rows += nlos_severity.claim_rows(
        paper_b.EXPERIMENT, nlos, (sm.input.nlos_campaign or [""])[0], sm.params.seed,
        lambda campaign, tables: paper_b.evaluate_runs(tables, campaign, spec, nlos.get("scenario"), sm.params.resample),
        paper_b.claims, sm.input.nlos_tables)
    rows += sensitivity.results_rows(paper_b.EXPERIMENT, grids, paper_b.claims)
    rows += paper_b.setup_rows(estimates, spec)
    claims_of.write_outputs(paper_b.EXPERIMENT, rows, decided, sm.output.results, sm.output.claims)

    Path(sm.output.tracks).write_bytes(figures.trajectories(paper_b.trajectory_panels(estimates)))
    if curve is not None:
        published = next((r["paper_value"] for r in rows if r["table"] == paper_b.SNR_TABLE and r["paper_value"]), None)
        Path(sm.output.snr).write_bytes(figures.curve_with_interval(
            {f"dead reckoning, {sm.params.snr_scenario} ({sm.params.snr_curve['runs']} runs)":
             curve.rename(columns={"snr_db": "x", "rmse_m": "value", "run_rmse_m": "run_values"})},
            "accelerometer SNR [dB]", "dead-reckoning RMSE [m]",
            "Paper B: dead reckoning against the accelerometer SNR",
            {"paper: IMU only, simulation (60 dB)": published} if published else None, logy=True))
    else:
        Path(sm.output.snr).write_bytes(figures.placeholder(
            "no SNR curve (it needs experiments.paper_b.snr_curve.runs > 0 and a simulation scenario)"))
    Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_b.cdf_panels(estimates), xmax=5.0))
    Path(sm.output.errors).write_bytes(figures.error_over_time(paper_b.error_panels(estimates)))
    log.info("paper B summary over %s", labels)


for label, campaign, out in each_scenario(sm.params.sources, sm.output, ("estimates", "metrics", "sensitivity")):
    run_scenario(label, campaign, out)
summarize()
