"""Snakemake adapter: paper C's P / PV / PVA EKF on every run of one scenario."""

import pandas as pd

from wsnloc.analysis.filter_quality import grouped_quality
from wsnloc.analysis.paper_bounds import PAPER_C_KEYS, paper_c_params
from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_c
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_c")
campaign = Campaign.load(sm.input.campaign)
settings = paper_c.Settings.from_config(sm.params.settings)
settings.check_against(campaign)
subsets = paper_c.subsets_of(settings, sm.params.label)
estimates, metrics, qualities = [], [], []
for name, run_tables in load_runs(sm.input.tables, paper_c.INPUT_TABLES, sm.input.imu_5hz).items():
    data = RunData(run_tables, campaign, None, name)
    est = paper_c.run(data, settings, subsets).assign(run=name)
    quality, efficiency = grouped_quality(data, est, PAPER_C_KEYS, paper_c_params(settings))
    estimates.append(est)
    qualities.append(quality.assign(run=name))
    metrics.append(paper_c.run_metrics(est, run_tables["truth"]).merge(efficiency, on=PAPER_C_KEYS)
                   .assign(run=name))
    log.info("%s done", name)
tables.write("estimates_paper_c", pd.concat(estimates, ignore_index=True), sm.output.estimates)
pd.concat(metrics, ignore_index=True).to_csv(sm.output.metrics, index=False, float_format="%.6g")
pd.concat(qualities, ignore_index=True).to_parquet(sm.output.quality, index=False, compression="zstd")
