"""Snakemake adapter: paper A tables, claims and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import claims as claims_of, paper_a, sensitivity
from wsnloc.io import tables
from wsnloc.report import figures
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_a_summary")
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
results.write(rows + claims_of.results_rows(paper_a.EXPERIMENT, decided), sm.output.results)
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": decided}, indent=1))
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_a.cdf_panels(estimates)))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_a.trajectory_panels(estimates)))
Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_a.anchor_curves(res, settings),
                                                             "Paper A: RMSE against the number of anchors"))
