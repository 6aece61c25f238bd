"""Snakemake adapter: ingest one shard of the runs of each of the job's scenarios into Parquet
tables and resample each run's IMU (config `resample`) in passing (see wsnloc.data_stage).

A run over the quarantine limits fails the job; its quarantine table is kept beside the
job's log (the task's keep_dir, logs/ingest/<job>/...), which Snakemake does not delete.
"""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from wsnloc.campaign import Campaign
from wsnloc.data_stage import ingest_shard
from wsnloc.errors import IngestError
from wsnloc.io.limits import QuarantineLimits

limits = QuarantineLimits(**sm.params.limits)
campaigns = {}
for task in sm.params.tasks:
    if task["campaign"] not in campaigns:
        campaigns[task["campaign"]] = Campaign.load(task["campaign"])
    campaign = campaigns[task["campaign"]].for_scenario(task["label"].split("/", 1)[1])   # a 3-D scenario's heights
    try:
        ingest_shard(task["format"], dict(zip(task["runs"], task["raw_dirs"])), campaign, task["tables"],
                     task["imu_5hz"], limits, sm.params.resample, task["keep_dir"], log)
    except IngestError as exc:
        log.error("%s: %s", task["label"], exc)
        raise
