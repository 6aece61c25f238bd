"""Snakemake adapter: paper C tables, claims and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis.paper_bounds import PAPER_C_KEYS, paper_bound_outputs, paper_c_main, paper_c_params
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import claims as claims_of, paper_c, sensitivity
from wsnloc.io import tables
from wsnloc.report import bound_figures, figures
from wsnloc.workflow import end_job, script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_c_summary")
settings = paper_c.Settings.from_config(sm.params.settings)
paper = read_yaml(sm.input.papers)["C"]
labels = list(sm.params.labels)
rows, per_run, speeds = [], {}, {}
for label, path in zip(labels, sm.input.metrics):
    speeds[label] = paper_c.speed_label(Campaign.load(sm.params.campaign_of[label]), label.split("/", 1)[1])
    per_run[label] = pd.read_csv(path)
    rows += paper_c.results_rows(per_run[label], label, speeds[label], settings, paper)
decided = paper_c.claims(per_run, speeds, settings)
grids = {label: pd.read_csv(path) for label, path in zip(labels, sm.input.sensitivity)}
rows += sensitivity.results_rows(paper_c.EXPERIMENT, grids, lambda m: paper_c.claims(m, speeds, settings))
estimates = {label: tables.read(p) for label, p in zip(labels, sm.input.estimates)}
rows += paper_c.setup_rows(estimates, settings)
qualities = {label: pd.read_parquet(p) for label, p in zip(labels, sm.input.quality)}
bound_rows, bound_panels, consistency_panels = paper_bound_outputs("C", qualities, PAPER_C_KEYS,
                                                                   paper_c_params(settings), paper_c_main(settings))
rows += bound_rows
results.write(rows + claims_of.results_rows(paper_c.EXPERIMENT, decided), sm.output.results)
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": decided}, indent=1))
Path(sm.output.bounds).write_bytes(bound_figures.pcrb_panels(bound_panels))
# Over time, the position ANEES of the main rows (ANIS with its band and verdict: the bound table, results.csv).
Path(sm.output.consistency).write_bytes(bound_figures.consistency_panels([p for p in consistency_panels if p[2] == "ANEES"]))
Path(sm.output.histogram).write_bytes(figures.error_histograms(
    paper_c.histogram_panels(estimates, settings), "Paper C: position error per model, all runs (their Fig. 4b)"))
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_c.cdf_panels(estimates, settings), xmax=1.5))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_c.trajectory_panels(estimates, settings)))
curves = paper_c.noise_curves(grids.get(settings.table_2_scenario, pd.DataFrame()), settings) \
    if settings.table_2_scenario in grids and not grids[settings.table_2_scenario].empty else {}
Path(sm.output.noise).write_bytes(figures.curve_with_interval(
    curves, "factor on the model's a-priori noise sigma", "Table I RMSE [m]",
    f"Paper C: RMSE against the a-priori noise, {settings.table_2_scenario} (first runs; PVA: assumed IMU)",
    logx=True)
    if curves else figures.placeholder("no sensitivity grid (experiments.paper_c.sensitivity.runs: 0)"))
Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_c.anchor_curves(res, settings),
                                                             "Paper C: RMSE against the number of beacons"))
end_job()
