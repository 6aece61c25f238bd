"""Snakemake adapter: simulate the runs of one shard of every simulated scenario of one format."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from pathlib import Path

from wsnloc.campaign import Campaign
from wsnloc.sim import SIMULATORS
from wsnloc.sim.seeding import run_seed_sequence
from wsnloc.workflow import SIMULATED_ROOT

campaigns = {}
for spec in sm.params.scenarios:
    dataset, scenario = spec["dataset"], spec["scenario"]
    if spec["campaign"] not in campaigns:
        campaigns[spec["campaign"]] = Campaign.load(spec["campaign"])
    campaign = campaigns[spec["campaign"]]
    simulate_run = SIMULATORS[campaign.format]
    for run in spec["runs"]:
        index = int(run.split("-")[1])           # run-07 -> 7: the seed depends on the run, not the shard
        seeds = run_seed_sequence(sm.params.seed, dataset, scenario, index)
        out = simulate_run(campaign, scenario, seeds, Path(SIMULATED_ROOT) / dataset / scenario / run,
                           meta={"run": run, "base_seed": sm.params.seed, "dataset": dataset})
        log.info("simulated %s", out)
