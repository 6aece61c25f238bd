"""Snakemake adapter: paper A's EKF rows on every run of one scenario."""

import json

import pandas as pd

from wsnloc.analysis.filter_quality import grouped_quality
from wsnloc.analysis.paper_bounds import PAPER_A_KEYS, paper_a_params
from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import calibration, paper_a, sensitivity
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import end_job, start_job

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = start_job(sm.log[0], "paper_a")
campaign = Campaign.load(sm.input.campaign)
settings = paper_a.Settings.from_config(sm.params.settings)
settings.check_against(campaign)
runs = load_runs(sm.input.tables, paper_a.INPUT_TABLES)
zigbee = list(campaign.anchors_of("zigbee")["anchor_id"])
models = calibration.rss_models_for_runs(runs, campaign, zigbee, settings.rss_calibration, settings.rss_model)
data = {name: RunData(run_tables, campaign, models[name], name) for name, run_tables in runs.items()}
estimates = [est.assign(run=name) for name, est in zip(runs, paper_a.run_all(list(data.values()), settings))]
bounded = grouped_quality([(data[name], est) for name, est in zip(runs, estimates)], PAPER_A_KEYS,
                          paper_a_params(settings))
metrics, qualities = [], []
for (name, run_tables), est, (quality, efficiency) in zip(runs.items(), estimates, bounded):
    qualities.append(quality.assign(run=name))
    metrics.append(paper_a.run_metrics(est, run_tables["truth"]).merge(efficiency, on=PAPER_A_KEYS).assign(run=name))
    log.info("%s: RSS model %s", name, json.dumps(models[name]))
tables.write("estimates_paper_a", pd.concat(estimates, ignore_index=True), sm.output.estimates)
metrics = pd.concat(metrics, ignore_index=True)
metrics.to_csv(sm.output.metrics, index=False, float_format="%.6g")
pd.concat(qualities, ignore_index=True).to_parquet(sm.output.quality, index=False, compression="zstd")


def variant_metrics(spec: dict, _, names: list[str]) -> pd.DataFrame:
    """Every row of the sampled runs under a scaled a-priori setting, stepped together."""
    estimates = paper_a.run_all([data[name] for name in names], paper_a.Settings.from_config(spec))
    return pd.concat([paper_a.run_metrics(est, runs[name]["truth"]).assign(run=name)
                      for name, est in zip(names, estimates)], ignore_index=True)


grid = sensitivity.grid_metrics(sm.params.settings, "experiments.paper_a", metrics, variant_metrics)
grid.to_csv(sm.output.sensitivity, index=False, float_format="%.6g")
end_job()
