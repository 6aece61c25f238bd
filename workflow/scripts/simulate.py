"""Snakemake adapter: simulate the runs of one shard of one scenario of a simulated dataset."""

from pathlib import Path

from wsnloc.campaign import Campaign
from wsnloc.sim import SIMULATORS
from wsnloc.sim.seeding import run_seed_sequence
from wsnloc.workflow import end_job, script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "simulate")
campaign = Campaign.load(sm.input.campaign)
simulate_run = SIMULATORS[campaign.format]
for run in sm.params.runs:
    index = int(run.split("-")[1])               # run-07 -> 7: the seed depends on the run, not the shard
    seeds = run_seed_sequence(sm.params.seed, sm.wildcards.dataset, sm.wildcards.scenario, index)
    out = simulate_run(campaign, sm.wildcards.scenario, seeds, Path(sm.params.root) / run,
                       meta={"run": run, "base_seed": sm.params.seed, "dataset": sm.wildcards.dataset})
    log.info("simulated %s", out)
end_job()
