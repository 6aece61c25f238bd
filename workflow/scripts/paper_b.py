"""Snakemake adapter: paper B estimators on every run of each of its scenarios."""

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_b, sensitivity
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import each_scenario, end_job, script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_b")


def run_scenario(label: str, campaign: Campaign, out: dict) -> None:
    """Every run of one scenario: estimates, per-run metrics and sensitivity grid written to
    out['estimates'], out['metrics'], out['sensitivity']."""
    spec = paper_b.scenario_config(sm.params.settings, label in sm.params.simulated)
    settings = paper_b.Settings.from_config(spec)
    settings.check_against(campaign)
    estimates, metrics, data = [], [], {}
    runs = load_runs(sm.params.sources["tables_of"][label], paper_b.INPUT_TABLES, sm.params.sources["imu_of"][label])
    for name, run_tables in runs.items():
        data[name] = RunData(run_tables, campaign, None, name)
        est = paper_b.run(data[name], settings).assign(run=name)
        estimates.append(est)
        metrics.append(paper_b.run_metrics(est, run_tables["truth"]).assign(run=name))
    tables.write("estimates_paper_b", pd.concat(estimates, ignore_index=True), out["estimates"])
    metrics = pd.concat(metrics, ignore_index=True)
    metrics.to_csv(out["metrics"], index=False, float_format="%.6g")

    def fusion_variant(spec: dict, sigma: str, run: str) -> pd.DataFrame:
        """The a-priori sigmas act on the fusions only: re-run those, keep the run's other methods."""
        fused = paper_b.run(data[run], paper_b.Settings.from_config(spec), paper_b.SENSITIVITY_METHODS)
        return sensitivity.replace_cells(metrics, run, paper_b.run_metrics(fused, runs[run]["truth"]), ["method"])

    grid = sensitivity.grid_metrics(spec, "experiments.paper_b", metrics, sensitivity.each_run(fusion_variant))
    grid.to_csv(out["sensitivity"], index=False, float_format="%.6g")
    log.info("%s: %d runs done", label, len(runs))


for label, campaign, out in each_scenario(sm.params.sources, sm.output, ("estimates", "metrics", "sensitivity")):
    run_scenario(label, campaign, out)
end_job()
