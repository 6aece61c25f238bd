"""Snakemake adapter: paper A over all its scenarios and runs; tables, claims, figures."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import calibration, paper_a
from wsnloc.metrics.data_quality import load_runs
from wsnloc.report import figures
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_a")
settings = paper_a.Settings.from_config(sm.params.settings)
paper = read_yaml(sm.input.papers)["A"]
rows, estimates = [], {}
for label in sm.params.labels:
    campaign = Campaign.load(sm.params.campaign_of[label])
    settings.check_against(campaign)
    runs = load_runs(sm.params.tables_of[label])
    zigbee = [a for a in campaign.anchors_of("zigbee")["anchor_id"]]
    models = calibration.rss_models_for_runs(runs, campaign, zigbee, settings.rss_calibration, settings.rss_model)
    metrics, scenario_estimates = [], []
    for name, run_tables in runs.items():
        est = paper_a.run(run_tables, campaign, settings, models[name]).assign(run=name)
        scenario_estimates.append(est)
        metrics.append(paper_a.run_metrics(est).assign(run=name))
        log.info("%s %s: RSS model %s", label, name, models[name])
    motion = campaign.section("scenarios", label.split("/", 1)[1])["motion"]
    rows += paper_a.results_rows(pd.concat(metrics), label, motion, settings, paper)
    estimates[label] = pd.concat(scenario_estimates, ignore_index=True)
results.write(rows, sm.output.results)
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": paper_a.claims(res, settings)}, indent=1))
Path(sm.output.cdf).write_bytes(figures.error_cdf(paper_a.cdf_panels(estimates)))
Path(sm.output.tracks).write_bytes(figures.trajectories(paper_a.trajectory_panels(estimates)))
Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_a.anchor_curves(res, settings),
                                                             "Paper A: RMSE against the number of anchors"))
