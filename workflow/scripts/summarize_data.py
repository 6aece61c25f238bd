"""Snakemake adapter: data summary and figures of each scenario of a dataset (all its shards'
tables; see wsnloc.data_stage.summarize_scenario)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from types import SimpleNamespace

from wsnloc.campaign import Campaign
from wsnloc.data_stage import summarize_scenario

campaign = Campaign.load(sm.input.campaign)
for task in sm.params.tasks:
    scenario = task["label"].split("/", 1)[1]
    summarize_scenario(task["tables"], task["imu_5hz"], campaign.for_scenario(scenario), task["label"],
                       SimpleNamespace(**task["outputs"]), log)
