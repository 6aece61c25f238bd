"""Shared fixtures: the repository paths, the Newcom++ campaign, one simulated run."""

from pathlib import Path

import pytest

from wsnloc.campaign import Campaign
from wsnloc.sim.newcom import simulate_run
from wsnloc.sim.seeding import run_seed_sequence

ROOT = Path(__file__).resolve().parents[1]
NEWCOM = ROOT / "config" / "campaigns" / "newcom.yaml"


@pytest.fixture(scope="session")
def campaign() -> Campaign:
    return Campaign.load(NEWCOM)


@pytest.fixture(scope="session")
def simulated_run(campaign, tmp_path_factory) -> Path:
    """One simulated run of the constant-speed scenario (read-only for tests)."""
    out = tmp_path_factory.mktemp("sim") / "run-01"
    return simulate_run(campaign, "constant", run_seed_sequence(7, "newcom", "constant", 1), out)
