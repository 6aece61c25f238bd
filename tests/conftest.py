"""Shared fixtures: the repository paths, the Newcom++ campaign, one simulated run."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from wsnloc.campaign import Campaign
from wsnloc.sim.newcom import simulate_run
from wsnloc.sim.seeding import run_seed_sequence

ROOT = Path(__file__).resolve().parents[1]
NEWCOM = ROOT / "config" / "campaigns" / "newcom.yaml"


@pytest.fixture(scope="session")
def campaign() -> Campaign:
    return Campaign.load(NEWCOM)


@pytest.fixture(scope="session")
def newcom() -> Campaign:
    """The Newcom++ campaign by the name the paper set-up and bound tests use."""
    return Campaign.load(NEWCOM)


@pytest.fixture(scope="session")
def cricket() -> Campaign:
    """The Cricket campaign (a test module may define its own `cricket` fixture instead)."""
    return Campaign.load(ROOT / "config" / "campaigns" / "cricket.yaml")


@pytest.fixture(scope="session")
def simulated_run(campaign, tmp_path_factory) -> Path:
    """One simulated run of the constant-speed scenario (read-only for tests)."""
    out = tmp_path_factory.mktemp("sim") / "run-01"
    return simulate_run(campaign, "constant", run_seed_sequence(7, "newcom", "constant", 1), out)


SMALL_WORKBENCH = ("tracker", "ekf", "pf", "ekf_rts", "sliding_window", "ekf_gate_nlos")   # cells kept


def small_workflow(target: Path, shards: int = 1) -> Path:
    """A copy of the workflow with a small configuration: 2 runs, one scenario per dataset (and
    newcom's tdoa and flight, 1 run each, for the workbench_spatial study); the opt-in
    sensitivity grids of papers A, B and D on."""
    target.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "Snakefile", target)
    shutil.copytree(ROOT / "workflow", target / "workflow")
    shutil.copytree(ROOT / "config", target / "config")
    shutil.copytree(ROOT / "profiles", target / "profiles")
    config = yaml.safe_load((target / "config" / "config.yaml").read_text())
    config["runs"] = 2
    config["shards"] = shards
    config["datasets"]["newcom"]["scenarios"] = ["constant", "tdoa", "flight"]
    config["datasets"]["newcom"]["scenario_runs"] = {"tdoa": 1, "flight": 1}   # fewer runs than `runs`
    config["datasets"]["cricket"]["scenarios"] = ["speed_40"]
    experiments = config["experiments"]
    experiments["paper_d"]["scenarios"] = ["newcom/constant"]
    experiments["paper_d"]["cost_iterations"] = 500
    experiments["paper_b"]["scenarios"] = ["newcom/constant"]
    experiments["paper_b"]["simulation_scenarios"] = []
    experiments["paper_b"]["overrides"] = {}      # its simulation scenario's
    experiments["paper_a"]["scenarios"] = ["newcom/constant"]
    experiments["paper_c"]["scenarios"] = ["cricket/speed_40"]
    experiments["paper_c"]["table_2_scenario"] = "cricket/speed_40"
    experiments["paper_c"]["overrides"] = {key: layer for key, layer in (experiments["paper_c"].get("overrides") or {}).items()
                                           if key in ("cricket", "cricket/speed_40")}   # its P sigma per speed
    for paper in ("paper_a", "paper_b", "paper_d"):    # the opt-in sensitivity grids on (paper C's stays off)
        experiments[paper]["sensitivity"]["runs"] = 2
    config["ranging_validation"]["scenarios"] = ["newcom/constant"]
    workbench = config["studies"]["workbench"]
    workbench["scenarios"] = ["newcom/constant", "cricket/speed_40"]
    workbench["estimators"] = {k: workbench["estimators"][k] for k in SMALL_WORKBENCH}
    assert config["studies"]["workbench_spatial"]["scenarios"] == ["newcom/tdoa", "newcom/flight"]   # kept as shipped
    (target / "config" / "config.yaml").write_text(yaml.safe_dump(config))
    return target


def snakemake(cwd, *args, timeout=900):
    return subprocess.run([sys.executable, "-m", "snakemake", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)
