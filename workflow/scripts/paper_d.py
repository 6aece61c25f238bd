"""Snakemake adapter: paper D estimators on every run of one scenario."""

import json

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_d, sensitivity
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_d")
campaign = Campaign.load(sm.input.campaign)
settings = paper_d.Settings.from_config(sm.params.settings)
settings.check_against(campaign)
runs = load_runs(sm.input.tables, paper_d.INPUT_TABLES)
models = paper_d.rss_models_for_runs(runs, campaign, settings)
estimates, metrics, data = [], [], {}
for name, run_tables in runs.items():
    data[name] = RunData(run_tables, campaign, models[name], name)
    est = paper_d.run(data[name], settings).assign(run=name)
    estimates.append(est)
    metrics.append(paper_d.run_metrics(est, run_tables["truth"])
                   .assign(run=name, **{f"rss_{k}": v for k, v in models[name].items()}))
    log.info("%s: RSS model %s", name, json.dumps(models[name]))
tables.write("estimates_paper_d", pd.concat(estimates, ignore_index=True), sm.output.estimates)
metrics = pd.concat(metrics, ignore_index=True)
metrics.to_csv(sm.output.metrics, index=False, float_format="%.6g")


def kalman_variant(spec: dict, sigma: str, run: str) -> pd.DataFrame:
    """Paper D's a-priori sigmas (paper_d.SENSITIVITY_SIGMAS) act on the KF cells only:
    re-run those, keep the run's other cells."""
    kalman = paper_d.run(data[run], paper_d.Settings.from_config(spec), stages=("kalman",))
    return sensitivity.replace_cells(metrics, run, paper_d.run_metrics(kalman, runs[run]["truth"]),
                                     ["localizer", "technique", "stage"])


grid = sensitivity.grid_metrics(sm.params.settings, "experiments.paper_d", metrics, sensitivity.each_run(kalman_variant),
                                paper_d.SENSITIVITY_SIGMAS)
grid.to_csv(sm.output.sensitivity, index=False, float_format="%.6g")
