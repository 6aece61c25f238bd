"""Snakemake adapter: paper D estimators on every run of one scenario."""

import json

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_d, sensitivity
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import end_job, start_job

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = start_job(sm.log[0], "paper_d")
campaign = Campaign.load(sm.input.campaign)
settings = paper_d.Settings.from_config(sm.params.settings)
settings.check_against(campaign)
runs = load_runs(sm.input.tables, paper_d.INPUT_TABLES)
models = paper_d.rss_models_for_runs(runs, campaign, settings)
data = {name: RunData(run_tables, campaign, models[name], name) for name, run_tables in runs.items()}
estimates = [est.assign(run=name) for name, est in zip(runs, paper_d.run_all(list(data.values()), settings))]
metrics = []
for (name, run_tables), est in zip(runs.items(), estimates):
    metrics.append(paper_d.run_metrics(est, run_tables["truth"])
                   .assign(run=name, **{f"rss_{k}": v for k, v in models[name].items()}))
    log.info("%s: RSS model %s", name, json.dumps(models[name]))
tables.write("estimates_paper_d", pd.concat(estimates, ignore_index=True), sm.output.estimates)
metrics = pd.concat(metrics, ignore_index=True)
metrics.to_csv(sm.output.metrics, index=False, float_format="%.6g")


def kalman_variant(spec: dict, sigma: str, names: list[str]) -> pd.DataFrame:
    """Paper D's a-priori sigmas (paper_d.SENSITIVITY_SIGMAS) act on the KF cells only:
    re-run those (all sampled runs together), keep each run's other cells."""
    reruns = paper_d.run_all([data[name] for name in names], paper_d.Settings.from_config(spec), stages=("kalman",))
    return pd.concat([sensitivity.replace_cells(metrics, name, paper_d.run_metrics(rerun, runs[name]["truth"]),
                                                ["localizer", "technique", "stage"]).assign(run=name)
                      for name, rerun in zip(names, reruns)], ignore_index=True)


grid = sensitivity.grid_metrics(sm.params.settings, "experiments.paper_d", metrics, kalman_variant,
                                paper_d.SENSITIVITY_SIGMAS)
grid.to_csv(sm.output.sensitivity, index=False, float_format="%.6g")
end_job()
