"""The data stage of a scenario, shared by the workflow's job scripts: raw logs of a shard of
runs -> Parquet tables (with a quarantine of unusable lines) and the IMU resampled to a low
rate (ingest jobs); the data summary of a scenario and its figures (summary jobs).

Each step reads what the previous one wrote to disk, exactly as separate jobs would, so a
simulated run, a real run and a re-run of one step take the same path.
"""

from __future__ import annotations

import json
from pathlib import Path

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.io import tables
from wsnloc.io.ingest import ingest_scenario
from wsnloc.io.limits import QuarantineLimits
from wsnloc.metrics.data_quality import SUMMARY_TABLES, imu_files, load_inventory, load_runs, run_folders, summarize
from wsnloc.metrics.ranging import fit_path_loss
from wsnloc.signal.resample import CHANNELS, resample_imu


def ingest_shard(fmt: str, raw_dirs: dict[str, str], campaign: Campaign, tables_dir, imu_dir,
                 limits: QuarantineLimits, resample: dict, keep_dir, log) -> dict:
    """Ingest the runs {run: raw folder} into tables_dir/<run>/*.parquet and write each run's IMU
    resampled to resample['rate_hz'] (config `resample`) as imu_dir/<run>.parquet.

    A run over the quarantine limits raises IngestError; its quarantine table is kept in
    keep_dir. Returns the inventory {run: {file: counts}}.
    """
    inventory = ingest_scenario(fmt, raw_dirs, campaign, tables_dir, limits, keep_dir=keep_dir)
    for run, files in inventory.items():
        log.info("%s: %s", run, {name: (f["data_lines"], f["quarantined"]) for name, f in files.items()})
    out = Path(imu_dir)
    out.mkdir(parents=True, exist_ok=True)
    for run in inventory:
        imu = tables.read(Path(tables_dir) / run / "imu.parquet", columns=["t", *CHANNELS])
        low = resample_imu(imu, resample["rate_hz"], resample["grid_rate_hz"], resample["max_gap_s"],
                           resample["kaiser_beta"])
        tables.write("imu_5hz", low, out / f"{run}.parquet", {"rate_hz": resample["rate_hz"],
                                                              "kaiser_beta": resample["kaiser_beta"]})
        log.info("%s: %d raw IMU samples -> %d at %g Hz (%d in gaps)", run, len(imu), len(low),
                 resample["rate_hz"], int(low["in_gap"].sum()))
    return inventory


def summarize_scenario(tables_dirs, imu_dirs, campaign: Campaign, label: str, outputs, log) -> None:
    """Data summary of every run of a scenario (all its shards' folders): the JSON summary, the
    results rows and three figures (range error, RSS against distance, IMU resampling), written
    to outputs.summary, .results, .range_error, .rss and .imu (SUMMARY_FILES of the rules)."""
    from wsnloc.report import figures    # here: only the job that summarizes loads matplotlib

    folders = run_folders(tables_dirs)
    runs = load_runs(tables_dirs, SUMMARY_TABLES)
    imu_rows = {run: tables.row_count(folder / "imu.parquet") for run, folder in folders.items()}
    imu_5hz = {run: tables.read(path) for run, path in imu_files(imu_dirs).items()}
    summary, rows, samples = summarize(runs, imu_5hz, campaign, label, imu_rows)
    summary["inventory"] = load_inventory(tables_dirs)
    Path(outputs.summary).write_text(json.dumps(summary, indent=1, default=float))
    results.write(rows, outputs.results)

    Path(outputs.range_error).write_bytes(figures.range_error_figure(samples["range_errors"],
                                                                     f"{label}: Range error"))
    rss = samples["rss"]
    pooled_fit = fit_path_loss(rss["rss_dbm"], rss["true_distance_m"]) if len(rss) else {}
    first = rss[rss["run"] == rss["run"].iloc[0]] if len(rss) else rss
    Path(outputs.rss).write_bytes(figures.rss_vs_distance(first, pooled_fit, summary["configured_path_loss"],
                                                          f"{label}: ZigBee RSS, first run"))
    first_run = next(iter(runs))
    Path(outputs.imu).write_bytes(figures.imu_resampling(tables.read(folders[first_run] / "imu.parquet"),
                                                         imu_5hz.get(first_run, tables.empty("imu_5hz")),
                                                         f"{label}: IMU resampling, {first_run}"))
    log.info("summarized %d runs of %s", len(runs), label)
