"""Snakemake adapter: paper D tables, claims, cost and figures over all scenarios."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.config import read_yaml
from wsnloc.analysis import nlos_severity
from wsnloc.experiments import claims as claims_of, paper_d, sensitivity
from wsnloc.io import tables
from wsnloc.report import figures
from wsnloc.workflow import end_job, start_job

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = start_job(sm.log[0], "paper_d_summary")
settings = paper_d.Settings.from_config(sm.params.settings)
labels = list(sm.params.labels)

per_run = {label: pd.read_csv(path) for label, path in zip(labels, sm.input.metrics)}
rows = [row for label in labels for row in paper_d.results_rows(per_run[label], label)]
paper_cost_ms = read_yaml(sm.input.papers)["D"]["cost_ms_per_step"]
counts = paper_d.operation_counts(settings)
decided = paper_d.claims(per_run) + [paper_d.cost_claim(counts, paper_cost_ms)]
cost = paper_d.measure_cost(settings)
rows += paper_d.cost_rows(cost, paper_cost_ms) + paper_d.operation_rows(counts, paper_cost_ms)
grids = {label: pd.read_csv(path) for label, path in zip(labels, sm.input.sensitivity)}
rows += nlos_severity.claim_rows(   # claims against NLOS ranging severity (opt-in)
    paper_d.EXPERIMENT, sm.params.settings.get("nlos_sweep"), (sm.input.nlos_campaign or [""])[0], sm.params.seed,
    lambda campaign, tables: paper_d.evaluate_runs(tables, campaign, settings), paper_d.claims, sm.input.nlos_tables)
rows += sensitivity.results_rows(paper_d.EXPERIMENT, grids, paper_d.claims)
estimates = {label: tables.read(p) for label, p in zip(labels, sm.input.estimates)}
rows += paper_d.setup_rows(estimates)
results.write(rows + claims_of.results_rows(paper_d.EXPERIMENT, decided), sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": decided}, indent=1))
# Wall-clock measurements live apart, so that everything else is byte-reproducible.
Path(sm.output.cost).write_text(json.dumps({"cost_us": cost}, indent=1))
log.info("cost per step (us): %s", cost)

Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_d.cdf_panels(estimates)))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_d.trajectory_panels(estimates)))
end_job()
