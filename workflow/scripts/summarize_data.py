"""Snakemake adapter: data summary and figures of one scenario whose runs were ingested in
several shards (with one shard, the ingest job writes them in passing)."""

from wsnloc.campaign import Campaign
from wsnloc.data_stage import summarize_scenario
from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (injected by wsnloc.job_server: the rule's input, output, params, wildcards, log)
log = start_job(sm.log[0], "summarize_data")
summarize_scenario(sm.input.tables, sm.input.imu_5hz, Campaign.load(sm.input.campaign), sm.params.label, sm.output,
                   log)
