"""Snakemake adapter: paper B estimators on every run of one scenario."""


import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_b, sensitivity
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_b")
campaign = Campaign.load(sm.input.campaign)
spec = paper_b.scenario_config(sm.params.settings, sm.params.simulated)
settings = paper_b.Settings.from_config(spec)
settings.check_against(campaign)
estimates, metrics, data = [], [], {}
runs = load_runs(sm.input.tables, paper_b.INPUT_TABLES, sm.input.imu_5hz)
for name, run_tables in runs.items():
    data[name] = RunData(run_tables, campaign, None, name)
    est = paper_b.run(data[name], settings).assign(run=name)
    estimates.append(est)
    metrics.append(paper_b.run_metrics(est, run_tables["truth"]).assign(run=name))
    log.info("%s done", name)
tables.write("estimates_paper_b", pd.concat(estimates, ignore_index=True), sm.output.estimates)
metrics = pd.concat(metrics, ignore_index=True)
metrics.to_csv(sm.output.metrics, index=False, float_format="%.6g")


def fusion_variant(spec: dict, sigma: str, run: str) -> pd.DataFrame:
    """The a-priori sigmas act on the fusions only: re-run those, keep the run's other methods."""
    fused = paper_b.run(data[run], paper_b.Settings.from_config(spec), paper_b.SENSITIVITY_METHODS)
    return sensitivity.replace_cells(metrics, run, paper_b.run_metrics(fused, runs[run]["truth"]), ["method"])


grid = sensitivity.grid_metrics(spec, "experiments.paper_b", metrics, sensitivity.each_run(fusion_variant))
grid.to_csv(sm.output.sensitivity, index=False, float_format="%.6g")
