"""Snakemake adapter: data summary and figures of one scenario whose runs were ingested in
several shards (with one shard, the ingest job writes them in passing)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from wsnloc.campaign import Campaign
from wsnloc.data_stage import summarize_scenario

summarize_scenario(sm.input.tables, sm.input.imu_5hz, Campaign.load(sm.input.campaign), sm.params.label, sm.output,
                   log)
