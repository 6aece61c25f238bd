"""Snakemake adapter: paper C tables, claims and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis.paper_bounds import PAPER_C_KEYS, paper_bound_outputs, paper_c_main, paper_c_params
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import paper_c
from wsnloc.io import tables
from wsnloc.report import bound_figures, figures
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_c_summary")
settings = paper_c.Settings.from_config(sm.params.settings)
paper = read_yaml(sm.input.papers)["C"]
labels = list(sm.params.labels)
rows, speeds = [], []
for label, path in zip(labels, sm.input.metrics):
    speed = paper_c.speed_label(Campaign.load(sm.params.campaign_of[label]), label.split("/", 1)[1])
    speeds.append(speed)
    rows += paper_c.results_rows(pd.read_csv(path), label, speed, settings, paper)
qualities = {label: pd.read_parquet(p) for label, p in zip(labels, sm.input.quality)}
bound_rows, bound_panels, consistency_panels = paper_bound_outputs("C", qualities, PAPER_C_KEYS,
                                                                   paper_c_params(settings), paper_c_main(settings))
rows += bound_rows
results.write(rows, sm.output.results)
Path(sm.output.bounds).write_bytes(bound_figures.pcrb_panels(bound_panels))
Path(sm.output.consistency).write_bytes(bound_figures.consistency_panels(consistency_panels))
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": paper_c.claims(res, speeds, settings)}, indent=1))
estimates = {label: tables.read(p) for label, p in zip(labels, sm.input.estimates)}
Path(sm.output.histogram).write_bytes(figures.error_histograms(
    paper_c.histogram_panels(estimates, settings), "Paper C: position error per model, all runs (their Fig. 4b)"))
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_c.cdf_panels(estimates, settings), xmax=1.5))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_c.trajectory_panels(estimates, settings)))
Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_c.anchor_curves(res, settings),
                                                             "Paper C: RMSE against the number of beacons"))
