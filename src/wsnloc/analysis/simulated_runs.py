"""Extra simulated runs for a sweep over a campaign setting, read by the project's reader.

The campaign simulator writes runs 1..`runs` of `scenario` with the seeds of the workflow's
runs (wsnloc.sim.seeding: run r of every sweep point shares its seed, so sweep points are
paired run by run) into a temporary directory, and the Newcom++ reader ingests them; only
the tables are kept.
"""

from __future__ import annotations

import copy
import tempfile
from pathlib import Path

from wsnloc.campaign import Campaign
from wsnloc.io.newcom import ingest_run
from wsnloc.sim.newcom import simulate_run
from wsnloc.sim.seeding import run_seed_sequence


def with_value(campaign: Campaign, keys: tuple[str, ...], value) -> Campaign:
    """A copy of the campaign with spec[keys[0]][keys[1]]... set to `value`."""
    spec = copy.deepcopy(campaign.spec)
    node = spec
    for key in keys[:-1]:
        node = node[key]
    if keys[-1] not in node:
        raise KeyError(f"{campaign.source}: no campaign key {'.'.join(keys)}")
    node[keys[-1]] = value
    return Campaign(campaign.name, campaign.format, spec, campaign.source)


def simulate_tables(campaign: Campaign, scenario: str, runs: int, seed: int,
                    dataset: str = "newcom") -> dict[str, dict]:
    """Tables (ranges, rss, imu, truth, anchors, ...) of runs 1..`runs`, by run name."""
    tables = {}
    with tempfile.TemporaryDirectory() as tmp:
        for run in range(1, runs + 1):
            run_dir = simulate_run(campaign, scenario, run_seed_sequence(seed, dataset, scenario, run),
                                   Path(tmp) / f"run-{run:02d}")
            tables[run_dir.name] = ingest_run(run_dir, campaign.for_scenario(scenario))[0]
    return tables
