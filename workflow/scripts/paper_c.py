"""Snakemake adapter: paper C over all its scenarios and runs; tables, claims, figures."""

import json
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.experiments import paper_c
from wsnloc.io import tables
from wsnloc.metrics.data_quality import imu_files, load_runs
from wsnloc.report import figures
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "paper_c")
settings = paper_c.Settings.from_config(sm.params.settings)
paper = read_yaml(sm.input.papers)["C"]
rows, speeds, histogram, cdf, tracks = [], [], {}, {}, {}
for label in sm.params.labels:
    imu_paths = imu_files(sm.params.imu_of[label])
    campaign = Campaign.load(sm.params.campaign_of[label])
    settings.check_against(campaign)
    subsets = settings.table_2_subsets if label == settings.table_2_scenario else [settings.table_1_subset]
    subsets = list(dict.fromkeys(subsets + [settings.table_1_subset]))
    metrics = []
    for name, run_tables in load_runs(sm.params.tables_of[label], paper_c.INPUT_TABLES).items():
        imu = tables.read(imu_paths[name])
        est = paper_c.run(run_tables, imu, campaign, settings, subsets)
        metrics.append(paper_c.run_metrics(est).assign(run=name))
        for model in paper_c.MODELS:
            sel = est[(est["model"] == model) & (est["subset"] == settings.table_1_subset)]
            cdf.setdefault(label, {}).setdefault(model, []).append(sel["error_m"].to_numpy())
        if label == settings.table_2_scenario and not tracks:
            tracks[f"{label}, {name}"] = (
                est[(est["model"] == "P") & (est["subset"] == settings.table_1_subset)][["true_x", "true_y"]]
                .rename(columns={"true_x": "x", "true_y": "y"}),
                {m: est[(est["model"] == m) & (est["subset"] == settings.table_1_subset)] for m in paper_c.MODELS})
        if label == settings.table_2_scenario:
            for model in paper_c.MODELS:
                sel = est[(est["model"] == model) & (est["subset"] == settings.table_1_subset)]
                histogram.setdefault(f"{model} ({label})", []).append(sel["error_m"].to_numpy())
        log.info("%s %s done", label, name)
    speed = paper_c.speed_label(campaign, label.split("/", 1)[1])
    speeds.append(speed)
    rows += paper_c.results_rows(pd.concat(metrics), label, speed, settings, paper)
results.write(rows, sm.output.results)
res = results.read(sm.output.results)
Path(sm.output.claims).write_text(json.dumps({"claims": paper_c.claims(res, speeds, settings)}, indent=1))
Path(sm.output.histogram).write_bytes(figures.error_histograms(
    {k: pd.Series(dtype=float) if not v else pd.concat(map(pd.Series, v)) for k, v in histogram.items()},
    "Paper C: position error per model, all runs (their Fig. 4b)"))
Path(sm.output.cdf).write_bytes(figures.error_cdf(
    {label: {m: np.concatenate(v) for m, v in models.items()} for label, models in cdf.items()}, xmax=1.5))
Path(sm.output.tracks).write_bytes(figures.trajectories(tracks))
Path(sm.output.anchors).write_bytes(figures.rmse_vs_anchors(paper_c.anchor_curves(res, settings),
                                                             "Paper C: RMSE against the number of beacons"))
