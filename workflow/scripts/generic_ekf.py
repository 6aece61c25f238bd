"""Snakemake adapter: the PV EKF on every run of the declared (generic) datasets."""


import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.experiments import generic_ekf
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "generic_ekf")
spec = sm.params.settings
runs, label_of = {}, {}
for label in sm.params.labels:
    campaign = Campaign.load(sm.params.campaign_of[label])
    for name, run_tables in load_runs(sm.params.tables_of[label]).items():
        runs[f"{label}/{name}"] = (run_tables, campaign)
        label_of[f"{label}/{name}"] = label
models = generic_ekf.calibrations(runs, spec["rss_model"])
metrics = {label: [] for label in sm.params.labels}
for key, (run_tables, campaign) in runs.items():
    estimates = generic_ekf.run(run_tables, campaign, spec, models[key])
    if len(estimates):
        metrics[label_of[key]].append(generic_ekf.run_metrics(estimates))
    log.info("%s: RSS model %s", key, models[key])
rows = [row for label, parts in metrics.items() if parts
        for row in generic_ekf.results_rows(pd.concat(parts), label)]
results.write(rows, sm.output.results)
