"""Snakemake adapter: paper A tables, claims and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis import static_share
from wsnloc.analysis.paper_bounds import PAPER_A_KEYS, paper_bound_outputs, paper_a_main, paper_a_params
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import claims as claims_of, paper_a, sensitivity
from wsnloc.io import tables
from wsnloc.report import bound_figures, figures
from wsnloc.workflow import end_job, start_job

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = start_job(sm.log[0], "paper_a_summary")
settings = paper_a.Settings.from_config(sm.params.settings)
paper = read_yaml(sm.input.papers)["A"]
labels = list(sm.params.labels)
rows, per_run, motions = [], {}, {}
for label, path in zip(labels, sm.input.metrics):
    motions[label] = Campaign.load(sm.params.campaign_of[label]).section("scenarios", label.split("/", 1)[1])["motion"]
    per_run[label] = pd.read_csv(path)
    rows += paper_a.results_rows(per_run[label], label, motions[label], settings, paper)
decided = paper_a.claims(per_run, motions, settings)
grids = {label: pd.read_csv(path) for label, path in zip(labels, sm.input.sensitivity)}
rows += sensitivity.results_rows(paper_a.EXPERIMENT, grids, lambda m: paper_a.claims(m, motions, settings))
estimates = {label: tables.read(p) for label, p in zip(labels, sm.input.estimates)}
rows += paper_a.setup_rows(estimates, settings)
qualities = {label: pd.read_parquet(p) for label, p in zip(labels, sm.input.quality)}
bound_rows, bound_panels, consistency_panels = paper_bound_outputs("A", qualities, PAPER_A_KEYS,
                                                                   paper_a_params(settings), paper_a_main(settings))
rows += bound_rows
sweep_spec = sm.params.settings.get("static_sweep") or {"runs": 0}
sweep = None
if sweep_spec["runs"]:
    dataset, scenario = sweep_spec["scenario"].split("/", 1)
    sweep = static_share.gain_against_rest(Campaign.load(sm.input.sweep_campaign[0]), scenario, sweep_spec["rests_s"],
                                           sweep_spec["runs"], sm.params.seed, sm.params.settings, dataset)
    rows += paper_a.static_sweep_rows(sweep, sweep_spec["scenario"])
results.write(rows + claims_of.results_rows(paper_a.EXPERIMENT, decided), sm.output.results)
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": decided}, indent=1))
Path(sm.output.bounds).write_bytes(bound_figures.pcrb_panels(bound_panels))
# Over time, the position ANEES of the main rows (ANIS with its band and verdict: the bound table, results.csv).
Path(sm.output.consistency).write_bytes(bound_figures.consistency_panels([p for p in consistency_panels if p[2] == "ANEES"]))
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_a.cdf_panels(estimates)))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_a.trajectory_panels(estimates)))
if sweep is not None:
    Path(sm.output.static).write_bytes(figures.curve_with_interval(
        {f"hybrid, {sweep_spec['scenario']} ({sweep_spec['runs']} runs per rest)": paper_a.static_sweep_curve(sweep)},
        "static share of the epochs", "Table II - Table I RMSE [m]",
        "Paper A: motion detection gain against the static share",
        {f"paper, {motion}": gain for motion, gain in paper_a.paper_gains(paper, settings).items()}))
else:
    Path(sm.output.static).write_bytes(
        figures.placeholder("no static-share sweep (experiments.paper_a.static_sweep.runs: 0)"))
Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_a.anchor_curves(res, settings),
                                                             "Paper A: RMSE against the number of anchors"))
end_job()
