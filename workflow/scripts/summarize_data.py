"""Snakemake adapter: data summary and figures of one scenario."""

import json
from pathlib import Path

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.io import tables
from wsnloc.metrics.data_quality import imu_files, load_inventory, load_runs, summarize
from wsnloc.metrics.ranging import fit_path_loss
from wsnloc.report import figures
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "summarize_data")
campaign = Campaign.load(sm.input.campaign)
runs = load_runs(sm.input.tables)
imu_5hz = {run: tables.read(path) for run, path in imu_files(sm.input.imu_5hz).items()}
summary, rows, samples = summarize(runs, imu_5hz, campaign, sm.params.label)
summary["inventory"] = load_inventory(sm.input.tables)

Path(sm.output.summary).write_text(json.dumps(summary, indent=1, default=float))
results.write(rows, sm.output.results)

label = sm.params.label
Path(sm.output.range_error).write_bytes(figures.range_error_figure(samples["range_errors"], f"{label}: Range error"))
rss = samples["rss"]
pooled_fit = fit_path_loss(rss["rss_dbm"], rss["true_distance_m"]) if len(rss) else {}
first = rss[rss["run"] == rss["run"].iloc[0]] if len(rss) else rss
Path(sm.output.rss).write_bytes(figures.rss_vs_distance(first, pooled_fit, summary["configured_path_loss"],
                                                        f"{label}: ZigBee RSS, first run"))
first_run = next(iter(runs))
Path(sm.output.imu).write_bytes(figures.imu_resampling(runs[first_run]["imu"], imu_5hz.get(first_run, tables.empty("imu_5hz")),
                                                       f"{label}: IMU resampling, {first_run}"))
log.info("summarized %d runs of %s", len(runs), label)
