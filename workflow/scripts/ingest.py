"""Snakemake adapter: ingest every run of one scenario into Parquet tables, and resample
each run's IMU table to a uniform low rate (config `resample`) in passing.

A run over the quarantine limits fails the job; its quarantine table is kept beside the
job's log (logs/ingest/<job>/<run>.quarantine.csv), which Snakemake does not delete.
"""

from pathlib import Path

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io.ingest import ingest_scenario
from wsnloc.io import tables
from wsnloc.io.limits import QuarantineLimits
from wsnloc.signal.resample import resample_imu
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "ingest")
campaign = Campaign.load(sm.input.campaign)
limits = QuarantineLimits(per_run=sm.params.max_quarantine_share, per_file=sm.params.max_quarantine_share_per_file)
try:
    inventory = ingest_scenario(sm.params.format, dict(zip(sm.params.runs, sm.params.raw_dirs)), campaign,
                                sm.output.tables, limits, keep_dir=Path(sm.log[0]).with_suffix(""))
except IngestError as exc:
    log.error("%s", exc)
    raise
for run, files in inventory.items():
    log.info("%s: %s", run, {name: (f["data_lines"], f["quarantined"]) for name, f in files.items()})

resample = sm.params.resample
out = Path(sm.output.imu_5hz)
out.mkdir(parents=True, exist_ok=True)
for run in inventory:
    imu = tables.read(Path(sm.output.tables) / run / "imu.parquet")
    low = resample_imu(imu, resample["rate_hz"], resample["grid_rate_hz"], resample["max_gap_s"], resample["kaiser_beta"])
    tables.write("imu_5hz", low, out / f"{run}.parquet", {"rate_hz": resample["rate_hz"],
                                                          "kaiser_beta": resample["kaiser_beta"]})
    log.info("%s: %d raw IMU samples -> %d at %g Hz (%d in gaps)", run, len(imu), len(low), resample["rate_hz"],
             int(low["in_gap"].sum()))
