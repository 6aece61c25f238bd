"""Snakemake adapter: paper C's P / PV / PVA EKF on every run of each of its scenarios, then the
paper's tables, claims and figures over all scenarios (read back from the scenarios' files)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from functools import partial
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis.filter_quality import grouped_quality
from wsnloc.analysis.paper_bounds import PAPER_C_KEYS, paper_bound_outputs, paper_c_main, paper_c_params
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import cells, claims as claims_of, paper_c, sensitivity, why
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.report import bound_figures, figures
from wsnloc.workflow import each_scenario, read_scenario_files

spec = sm.params.spec


def run_scenario(label: str, campaign: Campaign, out: dict) -> str:
    """Every run of one scenario: estimates, per-run metrics, consistency and sensitivity grid
    written to out['estimates'], out['metrics'], out['quality'], out['sensitivity']. Returns
    the scenario's speed label (paper_c.speed_label)."""
    subsets = paper_c.subsets_of(spec, label)
    runs = load_runs(sm.params.sources["tables_of"][label], paper_c.INPUT_TABLES, sm.params.sources["imu_of"][label])
    data = {name: RunData(run_tables, campaign, None, name) for name, run_tables in runs.items()}
    estimates = [est.assign(run=name) for name, est in zip(runs, paper_c.run_all(list(data.values()), spec, label,
                                                                                  subsets))]
    bounded = grouped_quality([(data[name], est) for name, est in zip(runs, estimates)], PAPER_C_KEYS,
                              partial(paper_c_params(spec), label))
    metrics, qualities = [], []
    for (name, run_tables), est, (quality, efficiency) in zip(runs.items(), estimates, bounded):
        qualities.append(quality.assign(run=name))
        metrics.append(paper_c.run_metrics(est, run_tables["truth"]).merge(efficiency, on=PAPER_C_KEYS)
                       .assign(run=name))
    tables.write("estimates_paper_c", pd.concat(estimates, ignore_index=True), out["estimates"])
    metrics = pd.concat(metrics, ignore_index=True)
    metrics.to_csv(out["metrics"], index=False, float_format="%.6g")
    pd.concat(qualities, ignore_index=True).to_parquet(out["quality"], index=False, compression="zstd")

    def model_variant(variant: dict, sigma: str, names: list[str]) -> pd.DataFrame:
        """Re-run only the motion models the scaled sigma acts on (cells.acted_on), on all
        sampled runs together; each run keeps its other cells."""
        models = [m for m in paper_c.MODELS if m in cells.acted_on(variant, sigma)]
        reruns = paper_c.run_all([data[name] for name in names], variant, label, subsets, models)
        return pd.concat([sensitivity.replace_cells(metrics, name, paper_c.run_metrics(rerun, runs[name]["truth"]),
                                                    ["subset", "model"]).assign(run=name)
                          for name, rerun in zip(names, reruns)], ignore_index=True)

    grid = sensitivity.grid_metrics(spec, cells.where(paper_c.PAPER), metrics, model_variant)
    grid.to_csv(out["sensitivity"], index=False, float_format="%.6g")
    log.info("%s: %d runs done", label, len(runs))
    return paper_c.speed_label(campaign, label.split("/", 1)[1])


def summarize(speeds: dict[str, str]) -> None:
    """Tables (results.csv), claims and figures of paper C over all its scenarios, from the
    files run_scenario wrote (metrics as written, to 6 significant digits)."""
    paper = read_yaml(sm.input.papers)["C"]
    labels = list(sm.params.sources["labels"])
    files = read_scenario_files(sm.output, labels)
    per_run, grids, estimates = files["metrics"], files["sensitivity"], files["estimates"]
    rows = [row for label in labels
            for row in paper_c.results_rows(per_run[label], label, speeds[label], spec, paper)]
    decided = why.explain_c(paper_c.claims(per_run, speeds, spec), per_run, speeds, spec["table_1_subset"],
                            spec["table_2_subsets"], spec["table_2_scenario"],
                            Campaign.load(sm.input.campaigns[0]).spec["path"].get("corner_radius_m", 0.0),
                            cells.params(spec, "PV", labels[0], "paper_c")["accel_sigma_mps2"])
    rows += sensitivity.results_rows(paper_c.EXPERIMENT, grids, lambda m: paper_c.claims(m, speeds, spec))
    rows += paper_c.setup_rows(estimates, spec)
    bound_rows, bound_panels, consistency_panels = paper_bound_outputs("C", files["quality"], PAPER_C_KEYS,
                                                                       paper_c_params(spec), paper_c_main(spec))
    rows += bound_rows
    claims_of.write_outputs(paper_c.EXPERIMENT, rows, decided, sm.output.results, sm.output.claims)
    res = results.read(sm.output.results)
    pcrb_png, anees_png = bound_figures.bound_and_anees_figures(bound_panels, consistency_panels)
    Path(sm.output.bounds).write_bytes(pcrb_png)
    Path(sm.output.consistency).write_bytes(anees_png)
    Path(sm.output.histogram).write_bytes(figures.error_histograms(
        paper_c.histogram_panels(estimates, spec), "Paper C: position error per model, all runs (their Fig. 4b)"))
    Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_c.cdf_panels(estimates, spec), xmax=1.5))
    Path(sm.output.tracks).write_bytes(figures.trajectories(paper_c.trajectory_panels(estimates, spec)))
    curves = paper_c.noise_curves(grids.get(spec["table_2_scenario"], pd.DataFrame()), spec) \
        if spec["table_2_scenario"] in grids and not grids[spec["table_2_scenario"]].empty else {}
    Path(sm.output.noise).write_bytes(figures.curve_with_interval(
        curves, "factor on the model's a-priori noise sigma", "Table I RMSE [m]",
        f"Paper C: RMSE against the a-priori noise, {spec['table_2_scenario']} (first runs; PVA: assumed IMU)",
        logx=True)
        if curves else figures.placeholder("no sensitivity grid (experiments.paper_c.sensitivity.runs: 0)"))
    Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_c.anchor_curves(res, spec),
                                                                 "Paper C: RMSE against the number of beacons"))


summarize({label: run_scenario(label, campaign, out) for label, campaign, out
           in each_scenario(sm.params.sources, sm.output, ("estimates", "metrics", "quality", "sensitivity"))})
