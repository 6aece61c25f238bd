"""Snakemake adapter: paper A's EKF rows on every run of each of its scenarios, then the paper's
tables, claims and figures over all scenarios (read back from the scenarios' files)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

import json
from functools import partial
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis import static_share
from wsnloc.analysis.filter_quality import grouped_quality
from wsnloc.analysis.paper_bounds import PAPER_A_KEYS, paper_a_main, paper_a_params, paper_bound_outputs
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import cells, claims as claims_of, paper_a, sensitivity, why
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.report import bound_figures, figures
from wsnloc.sim.trajectory import peak_acceleration
from wsnloc.workflow import each_scenario, read_scenario_files

spec = sm.params.spec


def run_scenario(label: str, campaign: Campaign, out: dict) -> dict:
    """Every run of one scenario (RSS models calibrated on another run): estimates, per-run
    metrics, consistency and sensitivity grid written to out['estimates'], out['metrics'],
    out['quality'], out['sensitivity']. Returns the scenario's campaign section (its motion)."""
    runs = load_runs(sm.params.sources["tables_of"][label], paper_a.INPUT_TABLES)
    models = paper_a.rss_models_for_runs(runs, campaign, spec, label)
    data = {name: RunData(run_tables, campaign, models[name], name) for name, run_tables in runs.items()}
    estimates = [est.assign(run=name) for name, est in zip(runs, paper_a.run_all(list(data.values()), spec, label))]
    bounded = grouped_quality([(data[name], est) for name, est in zip(runs, estimates)], PAPER_A_KEYS,
                              partial(paper_a_params(spec), label))
    metrics, qualities = [], []
    for (name, run_tables), est, (quality, efficiency) in zip(runs.items(), estimates, bounded):
        qualities.append(quality.assign(run=name))
        metrics.append(paper_a.run_metrics(est, run_tables["truth"]).merge(efficiency, on=PAPER_A_KEYS)
                       .assign(run=name))
        log.info("%s: RSS model %s", name, json.dumps(models[name]))
    tables.write("estimates_paper_a", pd.concat(estimates, ignore_index=True), out["estimates"])
    metrics = pd.concat(metrics, ignore_index=True)
    metrics.to_csv(out["metrics"], index=False, float_format="%.6g")
    pd.concat(qualities, ignore_index=True).to_parquet(out["quality"], index=False, compression="zstd")

    def variant_metrics(variant: dict, _, names: list[str]) -> pd.DataFrame:
        """Every row of the sampled runs under a scaled a-priori setting, stepped together."""
        estimates = paper_a.run_all([data[name] for name in names], variant, label)
        return pd.concat([paper_a.run_metrics(est, runs[name]["truth"]).assign(run=name)
                          for name, est in zip(names, estimates)], ignore_index=True)

    grid = sensitivity.grid_metrics(spec, cells.where(paper_a.PAPER), metrics, variant_metrics)
    grid.to_csv(out["sensitivity"], index=False, float_format="%.6g")
    log.info("%s: %d runs done", label, len(runs))
    return campaign.section("scenarios", label.split("/", 1)[1])


def summarize(scenarios: dict[str, dict]) -> None:
    """Tables (results.csv), claims and figures of paper A over all its scenarios (their campaign
    sections), from the files run_scenario wrote (metrics as written, to 6 significant digits),
    with the opt-in static-share sweep."""
    motions = {label: section["motion"] for label, section in scenarios.items()}
    paper = read_yaml(sm.input.papers)["A"]
    labels = list(sm.params.sources["labels"])
    files = read_scenario_files(sm.output, labels)
    per_run, estimates = files["metrics"], files["estimates"]
    rows = [row for label in labels
            for row in paper_a.results_rows(per_run[label], label, motions[label], spec, paper)]
    decided = why.explain_a(paper_a.claims(per_run, motions, spec), per_run,
                            [paper_a.row_label(r) for r in spec["rows"]],
                            {label: peak_acceleration(section) for label, section in scenarios.items()},
                            {label: cells.params(spec, paper_a.TABLES[0], label, paper_a.PAPER)["accel_sigma_mps2"]
                             for label in labels})
    rows += sensitivity.results_rows(paper_a.EXPERIMENT, files["sensitivity"],
                                     lambda m: paper_a.claims(m, motions, spec))
    rows += paper_a.setup_rows(estimates, spec)
    bound_rows, bound_panels, consistency_panels = paper_bound_outputs("A", files["quality"], PAPER_A_KEYS,
                                                                       paper_a_params(spec), paper_a_main(spec))
    rows += bound_rows
    sweep_spec = spec.get("static_sweep") or {"runs": 0}
    sweep = None
    if sweep_spec["runs"]:
        dataset, scenario = sweep_spec["scenario"].split("/", 1)
        sweep = static_share.gain_against_rest(Campaign.load(sm.input.sweep_campaign[0]), scenario,
                                               sweep_spec["rests_s"], sweep_spec["runs"], sm.params.seed,
                                               spec, dataset)
        rows += paper_a.static_sweep_rows(sweep, sweep_spec["scenario"])
    claims_of.write_outputs(paper_a.EXPERIMENT, rows, decided, sm.output.results, sm.output.claims)
    res = results.read(sm.output.results)
    pcrb_png, anees_png = bound_figures.bound_and_anees_figures(bound_panels, consistency_panels)
    Path(sm.output.bounds).write_bytes(pcrb_png)
    Path(sm.output.consistency).write_bytes(anees_png)
    Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_a.cdf_panels(estimates)))
    Path(sm.output.tracks).write_bytes(figures.trajectories(paper_a.trajectory_panels(estimates)))
    if sweep is not None:
        Path(sm.output.static).write_bytes(figures.curve_with_interval(
            {f"hybrid, {sweep_spec['scenario']} ({sweep_spec['runs']} runs per rest)":
             paper_a.static_sweep_curve(sweep)},
            "static share of the epochs", "Table II - Table I RMSE [m]",
            "Paper A: motion detection gain against the static share",
            {f"paper, {motion}": gain for motion, gain in paper_a.paper_gains(paper, spec).items()}))
    else:
        Path(sm.output.static).write_bytes(
            figures.placeholder("no static-share sweep (experiments.paper_a.static_sweep.runs: 0)"))
    Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_a.anchor_curves(res, spec),
                                                                 "Paper A: RMSE against the number of anchors"))


summarize({label: run_scenario(label, campaign, out) for label, campaign, out
           in each_scenario(sm.params.sources, sm.output, ("estimates", "metrics", "quality", "sensitivity"))})
