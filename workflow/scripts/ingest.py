"""Snakemake adapter: ingest one shard of a scenario's runs into Parquet tables, resample
each run's IMU (config `resample`) in passing and, when the shard holds all the scenario's
runs, write the scenario's data summary (see wsnloc.data_stage).

A run over the quarantine limits fails the job; its quarantine table is kept beside the
job's log (logs/ingest/<job>/<run>.quarantine.csv), which Snakemake does not delete.
"""

from pathlib import Path

from wsnloc.campaign import Campaign
from wsnloc.data_stage import ingest_shard, summarize_scenario
from wsnloc.errors import IngestError
from wsnloc.io.limits import QuarantineLimits
from wsnloc.workflow import end_job, start_job

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = start_job(sm.log[0], "ingest")
campaign = Campaign.load(sm.input.campaign)
limits = QuarantineLimits(per_run=sm.params.max_quarantine_share, per_file=sm.params.max_quarantine_share_per_file)
try:
    ingest_shard(sm.params.format, dict(zip(sm.params.runs, sm.params.raw_dirs)), campaign, sm.output.tables,
                 sm.output.imu_5hz, limits, sm.params.resample, Path(sm.log[0]).with_suffix(""), log)
except IngestError as exc:
    log.error("%s", exc)
    raise
if "summary" in sm.output.keys():
    summarize_scenario(sm.output.tables, sm.output.imu_5hz, campaign, sm.params.label, sm.output, log)
end_job()
