"""Snakemake adapter: paper A tables, claims and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis.paper_bounds import PAPER_A_KEYS, paper_bound_outputs, paper_a_main, paper_a_params
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import paper_a
from wsnloc.io import tables
from wsnloc.report import bound_figures, figures
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_a_summary")
settings = paper_a.Settings.from_config(sm.params.settings)
paper = read_yaml(sm.input.papers)["A"]
labels = list(sm.params.labels)
rows = []
for label, path in zip(labels, sm.input.metrics):
    motion = Campaign.load(sm.params.campaign_of[label]).section("scenarios", label.split("/", 1)[1])["motion"]
    rows += paper_a.results_rows(pd.read_csv(path), label, motion, settings, paper)
qualities = {label: pd.read_parquet(p) for label, p in zip(labels, sm.input.quality)}
bound_rows, bound_panels, consistency_panels = paper_bound_outputs("A", qualities, PAPER_A_KEYS,
                                                                   paper_a_params(settings), paper_a_main(settings))
rows += bound_rows
results.write(rows, sm.output.results)
Path(sm.output.bounds).write_bytes(bound_figures.pcrb_panels(bound_panels))
Path(sm.output.consistency).write_bytes(bound_figures.consistency_panels(consistency_panels))
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": paper_a.claims(res, settings)}, indent=1))
estimates = {label: tables.read(p) for label, p in zip(labels, sm.input.estimates)}
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_a.cdf_panels(estimates)))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_a.trajectory_panels(estimates)))
Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_a.anchor_curves(res, settings),
                                                             "Paper A: RMSE against the number of anchors"))
