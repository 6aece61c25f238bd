"""Snakemake adapter: paper B tables, claims and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis import imu_snr, nlos_severity
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import claims as claims_of, paper_b, sensitivity
from wsnloc.io import tables
from wsnloc.report import figures
from wsnloc.workflow import end_job, script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_b_summary")
paper = read_yaml(sm.input.papers)["B"]
labels, simulated = list(sm.params.labels), set(sm.params.simulated)
per_run = {label: pd.read_csv(path) for label, path in zip(labels, sm.input.metrics)}
rows = [row for label in labels for row in paper_b.results_rows(per_run[label], label, paper, label in simulated)]
decided = paper_b.claims(per_run)
curve = None
if sm.params.snr_curve["runs"] and sm.params.snr_scenario:
    dataset, scenario = sm.params.snr_scenario.split("/", 1)
    curve = imu_snr.rmse_against_snr(Campaign.load(sm.input.snr_campaign[0]), scenario, sm.params.snr_curve["snrs_db"],
                                      sm.params.snr_curve["runs"], sm.params.seed, sm.params.resample,
                                      paper_b.scenario_config(sm.params.settings, True)["static_bias_s"], dataset)
    rows += paper_b.snr_rows(curve, sm.params.snr_scenario, paper)
grids = {label: pd.read_csv(path) for label, path in zip(labels, sm.input.sensitivity)}
nlos = sm.params.settings.get("nlos_sweep") or {"runs": 0}   # claims against NLOS ranging severity (opt-in)
nlos_settings = paper_b.Settings.from_config(
    paper_b.scenario_config(sm.params.settings, nlos.get("scenario") in simulated))
rows += nlos_severity.claim_rows(
    paper_b.EXPERIMENT, nlos, (sm.input.nlos_campaign or [""])[0], sm.params.seed,
    lambda campaign, tables: paper_b.evaluate_runs(tables, campaign, nlos_settings, sm.params.resample), paper_b.claims,
    sm.input.nlos_tables)
rows += sensitivity.results_rows(paper_b.EXPERIMENT, grids, paper_b.claims)
estimates = {label: tables.read(p) for label, p in zip(labels, sm.input.estimates)}
rows += paper_b.setup_rows(estimates)
results.write(rows + claims_of.results_rows(paper_b.EXPERIMENT, decided), sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": decided}, indent=1))

Path(sm.output.tracks).write_bytes(figures.trajectories(paper_b.trajectory_panels(estimates)))
if curve is not None:
    published = next((r["paper_value"] for r in rows if r["table"] == paper_b.SNR_TABLE and r["paper_value"]), None)
    Path(sm.output.snr).write_bytes(figures.curve_with_interval(
        {f"dead reckoning, {sm.params.snr_scenario} ({sm.params.snr_curve['runs']} runs)":
         curve.rename(columns={"snr_db": "x", "rmse_m": "value"})},
        "accelerometer SNR [dB]", "dead-reckoning RMSE [m]", "Paper B: dead reckoning against the accelerometer SNR",
        {"paper: IMU only, simulation (60 dB)": published} if published else None, logy=True))
else:
    Path(sm.output.snr).write_bytes(figures.placeholder(
        "no SNR curve (it needs experiments.paper_b.snr_curve.runs > 0 and a simulation scenario)"))
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_b.cdf_panels(estimates), xmax=5.0))
Path(sm.output.errors).write_bytes(figures.error_over_time(paper_b.error_panels(estimates)))
log.info("paper B summary over %s", labels)
end_job()
