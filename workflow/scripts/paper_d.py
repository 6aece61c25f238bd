"""Snakemake adapter: paper D estimators on every run of each of its scenarios, then the paper's
tables, claims, cost and figures over all scenarios (read back from the scenarios' files)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

import json
from pathlib import Path

import pandas as pd

from wsnloc.analysis import nlos_severity
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import cells, claims as claims_of, paper_d, sensitivity, why
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.report import figures
from wsnloc.workflow import each_scenario, read_scenario_files

spec = sm.params.spec


def run_scenario(label: str, campaign: Campaign, out: dict) -> None:
    """Every run of one scenario (RSS models calibrated on another run): estimates, per-run
    metrics and sensitivity grid written to out['estimates'], out['metrics'], out['sensitivity']."""
    runs = load_runs(sm.params.sources["tables_of"][label], paper_d.INPUT_TABLES)
    models = paper_d.rss_models_for_runs(runs, campaign, spec, label)
    data = {name: RunData(run_tables, campaign, models[name], name) for name, run_tables in runs.items()}
    estimates = [est.assign(run=name) for name, est in zip(runs, paper_d.run_all(list(data.values()), spec, label))]
    speed = paper_d.speed_input_metrics(list(data.values()), spec, label)      # the KF's speed input, checked
    metrics = []
    for (name, run_tables), est, fed in zip(runs.items(), estimates, speed):
        metrics.append(paper_d.run_metrics(est, run_tables["truth"]).merge(fed, how="left")
                       .assign(run=name, **{f"rss_{k}": v for k, v in models[name].items()}))
        log.info("%s: RSS model %s", name, json.dumps(models[name]))
    tables.write("estimates_paper_d", pd.concat(estimates, ignore_index=True), out["estimates"])
    metrics = pd.concat(metrics, ignore_index=True)
    metrics.to_csv(out["metrics"], index=False, float_format="%.6g")

    def tracker_variant(variant: dict, sigma: str, names: list[str]) -> pd.DataFrame:
        """Re-run the tracker cells the scaled sigma acts on (cells.acted_on; paper D's a-priori
        sigmas are the KF's), all sampled runs together; keep each run's other cells."""
        stages = [stage for stage in paper_d.TRACKERS if stage in cells.acted_on(variant, sigma)]
        reruns = paper_d.run_all([data[name] for name in names], variant, label, stages)
        return pd.concat([sensitivity.replace_cells(metrics, name, paper_d.run_metrics(rerun, runs[name]["truth"]),
                                                    ["localizer", "technique", "stage"]).assign(run=name)
                          for name, rerun in zip(names, reruns)], ignore_index=True)

    grid = sensitivity.grid_metrics(spec, cells.where(paper_d.PAPER), metrics, tracker_variant)
    grid.to_csv(out["sensitivity"], index=False, float_format="%.6g")
    log.info("%s: %d runs done", label, len(runs))


def summarize() -> None:
    """Tables (results.csv), claims, measured cost and figures of paper D over all its
    scenarios, from the files run_scenario wrote (metrics as written, to 6 significant
    digits), with the opt-in NLOS-severity sweep."""
    labels = list(sm.params.sources["labels"])

    files = read_scenario_files(sm.output, labels)
    per_run, grids, estimates = files["metrics"], files["sensitivity"], files["estimates"]
    rows = [row for label in labels for row in paper_d.results_rows(per_run[label], label, spec)]
    paper_cost_ms = read_yaml(sm.input.papers)["D"]["cost_ms_per_step"]
    counts = paper_d.operation_counts(spec, labels[0])
    shared = cells.params(spec, "velocity", labels[0], "paper_d")
    decided = why.explain_d(paper_d.claims(per_run) + [paper_d.cost_claim(counts, paper_cost_ms)], per_run,
                            shared["pmix_toa_weight"], shared["k_smallest"])
    cost = paper_d.measure_cost(spec, labels[0])
    rows += paper_d.cost_rows(cost, paper_cost_ms) + paper_d.operation_rows(counts, paper_cost_ms)
    rows += nlos_severity.claim_rows(   # claims against NLOS ranging severity (opt-in)
        paper_d.EXPERIMENT, spec.get("nlos_sweep"), (sm.input.nlos_campaign or [""])[0], sm.params.seed,
        lambda campaign, tables: paper_d.evaluate_runs(tables, campaign, spec, spec["nlos_sweep"]["scenario"]),
        paper_d.claims,
        sm.input.nlos_tables)
    rows += sensitivity.results_rows(paper_d.EXPERIMENT, grids, paper_d.claims)
    rows += paper_d.setup_rows(estimates)
    claims_of.write_outputs(paper_d.EXPERIMENT, rows, decided, sm.output.results, sm.output.claims)
    # Wall-clock measurements live apart, so that everything else is byte-reproducible.
    Path(sm.output.cost).write_text(json.dumps({"cost_us": cost}, indent=1))
    log.info("cost per step (us): %s", cost)

    Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_d.cdf_panels(estimates)))
    Path(sm.output.tracks).write_bytes(figures.trajectories(paper_d.trajectory_panels(estimates)))


for label, campaign, out in each_scenario(sm.params.sources, sm.output, ("estimates", "metrics", "sensitivity")):
    run_scenario(label, campaign, out)
summarize()
