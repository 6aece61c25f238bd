"""Snakemake adapter: paper B estimators on every run of one scenario."""


import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_b
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_b")
campaign = Campaign.load(sm.input.campaign)
settings = paper_b.Settings.from_config(sm.params.settings)
settings.check_against(campaign)
estimates, metrics = [], []
for name, run_tables in load_runs(sm.input.tables, paper_b.INPUT_TABLES, sm.input.imu_5hz).items():
    est = paper_b.run(RunData(run_tables, campaign, None, name), settings).assign(run=name)
    estimates.append(est)
    metrics.append(paper_b.run_metrics(est, run_tables["truth"]).assign(run=name))
    log.info("%s done", name)
tables.write("estimates_paper_b", pd.concat(estimates, ignore_index=True), sm.output.estimates)
pd.concat(metrics, ignore_index=True).to_csv(sm.output.metrics, index=False, float_format="%.6g")
