"""Snakemake adapter: paper D tables, claims, cost and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.config import read_yaml
from wsnloc.experiments import paper_d
from wsnloc.io import tables
from wsnloc.report import figures
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_d_summary")
settings = paper_d.Settings.from_config(sm.params.settings)
labels = list(sm.params.labels)

rows = []
for label, path in zip(labels, sm.input.metrics):
    rows += paper_d.results_rows(pd.read_csv(path), label)
paper_cost_ms = read_yaml(sm.input.papers)["D"]["cost_ms_per_step"]
cost = paper_d.measure_cost(settings)
rows += paper_d.cost_rows(cost, paper_cost_ms)
results.write(rows, sm.output.results)
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": paper_d.claims(res, labels)}, indent=1))
# Wall-clock measurements live apart, so that everything else is byte-reproducible.
Path(sm.output.cost).write_text(json.dumps({"claims": [paper_d.cost_claim(cost, paper_cost_ms)], "cost_us": cost},
                                           indent=1))
log.info("cost per step (us): %s", cost)

estimates = {label: tables.read(p) for label, p in zip(labels, sm.input.estimates)}
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_d.cdf_panels(estimates)))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_d.trajectory_panels(estimates)))
