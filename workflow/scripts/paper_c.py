"""Snakemake adapter: paper C's P / PV / PVA EKF on every run of each of its scenarios."""

import pandas as pd

from wsnloc.analysis.filter_quality import grouped_quality
from wsnloc.analysis.paper_bounds import PAPER_C_KEYS, paper_c_params
from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_c, sensitivity
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.workflow import each_scenario, end_job, script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_c")
settings = paper_c.Settings.from_config(sm.params.settings)


def run_scenario(label: str, campaign: Campaign, out: dict) -> None:
    """Every run of one scenario: estimates, per-run metrics, consistency and sensitivity grid
    written to out['estimates'], out['metrics'], out['quality'], out['sensitivity']."""
    settings.check_against(campaign)
    subsets = paper_c.subsets_of(settings, label)
    runs = load_runs(sm.params.sources["tables_of"][label], paper_c.INPUT_TABLES, sm.params.sources["imu_of"][label])
    data = {name: RunData(run_tables, campaign, None, name) for name, run_tables in runs.items()}
    estimates = [est.assign(run=name) for name, est in zip(runs, paper_c.run_all(list(data.values()), settings,
                                                                                  subsets))]
    bounded = grouped_quality([(data[name], est) for name, est in zip(runs, estimates)], PAPER_C_KEYS,
                              paper_c_params(settings))
    metrics, qualities = [], []
    for (name, run_tables), est, (quality, efficiency) in zip(runs.items(), estimates, bounded):
        qualities.append(quality.assign(run=name))
        metrics.append(paper_c.run_metrics(est, run_tables["truth"]).merge(efficiency, on=PAPER_C_KEYS)
                       .assign(run=name))
    tables.write("estimates_paper_c", pd.concat(estimates, ignore_index=True), out["estimates"])
    metrics = pd.concat(metrics, ignore_index=True)
    metrics.to_csv(out["metrics"], index=False, float_format="%.6g")
    pd.concat(qualities, ignore_index=True).to_parquet(out["quality"], index=False, compression="zstd")

    def model_variant(spec: dict, sigma: str, names: list[str]) -> pd.DataFrame:
        """Re-run only the motion models the scaled sigma acts on (paper_c.SIGMA_MODELS), on all
        sampled runs together; each run keeps its other cells."""
        models = paper_c.SIGMA_MODELS[sigma]
        reruns = paper_c.run_all([data[name] for name in names], paper_c.Settings.from_config(spec), subsets, models)
        return pd.concat([sensitivity.replace_cells(metrics, name, paper_c.run_metrics(rerun, runs[name]["truth"]),
                                                    ["subset", "model"]).assign(run=name)
                          for name, rerun in zip(names, reruns)], ignore_index=True)

    grid = sensitivity.grid_metrics(sm.params.settings, "experiments.paper_c", metrics, model_variant,
                                    tuple(paper_c.SIGMA_MODELS))
    grid.to_csv(out["sensitivity"], index=False, float_format="%.6g")
    log.info("%s: %d runs done", label, len(runs))


for label, campaign, out in each_scenario(sm.params.sources, sm.output,
                                          ("estimates", "metrics", "quality", "sensitivity")):
    run_scenario(label, campaign, out)
end_job()
