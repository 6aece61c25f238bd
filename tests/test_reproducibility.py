"""Reproducibility and interruption: cold builds from scratch give identical processed
tables, results and figures; a build killed mid-way and resumed gives the same again.

Compared: every Parquet, JSON and figure file under data/processed, and reports/results.csv,
except the wall-clock measurements (paper D's cost per step: its cost.json and results
rows). The HTML carries its build time and is not compared. A build killed with SIGKILL
leaves Snakemake's lock behind: the documented recovery is `--unlock`, then
`--rerun-incomplete`.
"""

import hashlib
import os
import re
import signal
import subprocess
import sys
import time

import pandas as pd
import pytest

from conftest import small_workflow, snakemake

TIMING_METRICS = {"us_per_step", "ratio", "time_per_step_us"}   # paper D cost; study cells


def fingerprint(work) -> dict[str, str]:
    """Digests by path, with the shard folder left out (sharding must not change results)."""
    files = sorted(p for p in (work / "data" / "processed").rglob("*")
                   if p.suffix in (".parquet", ".png", ".json") and p.name not in ("cost.json", "inventory.json"))
    digests = {re.sub(r"/shard-\d+/", "/", str(p.relative_to(work))): hashlib.sha256(p.read_bytes()).hexdigest()
               for p in files}
    results = pd.read_csv(work / "reports" / "results.csv")
    stable = results[~results["metric"].isin(TIMING_METRICS)].to_csv(index=False)
    digests["reports/results.csv (without timing rows)"] = hashlib.sha256(stable.encode()).hexdigest()
    return digests


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    work = small_workflow(tmp_path_factory.mktemp("cold-a"))
    result = snakemake(work, "--cores", "2")
    assert result.returncode == 0, result.stderr[-3000:]
    return fingerprint(work)


def test_two_cold_builds_are_identical(reference, tmp_path):
    work = small_workflow(tmp_path / "cold-b")
    result = snakemake(work, "--cores", "2")
    assert result.returncode == 0, result.stderr[-3000:]
    assert len(reference) > 40
    assert fingerprint(work) == reference


def test_killed_build_resumes_to_the_same_results(reference, tmp_path):
    work = small_workflow(tmp_path / "killed")
    process = subprocess.Popen([sys.executable, "-m", "snakemake", "--cores", "2"], cwd=work,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (work / "data" / "processed" / "newcom" / "constant" / "tables" / "shard-1").exists():
        time.sleep(0.2)
    time.sleep(1.0)
    assert process.poll() is None, "the build finished before it could be interrupted"
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert not (work / "reports" / "results.csv").exists()
    assert snakemake(work, "--unlock").returncode == 0
    result = snakemake(work, "--cores", "2", "--rerun-incomplete")
    assert result.returncode == 0, result.stderr[-3000:]
    assert fingerprint(work) == reference


def test_sharded_build_gives_the_same_results(reference, tmp_path):
    work = small_workflow(tmp_path / "sharded", shards=2)
    result = snakemake(work, "--cores", "2")
    assert result.returncode == 0, result.stderr[-3000:]
    assert (work / "data" / "processed" / "newcom" / "constant" / "tables" / "shard-2" / "run-02").is_dir()
    assert fingerprint(work) == reference


def test_slurm_profile_plans_the_sharded_dag(tmp_path):
    pytest.importorskip("snakemake_executor_plugin_slurm", reason="pip install -e '.[cluster]'")
    work = small_workflow(tmp_path / "slurm")
    result = snakemake(work, "-n", "--profile", "profiles/slurm", "--config", "runs=4", "shards=4")
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-3000:]
    assert "simulate_newcom_shard4" in output and "This was a dry-run" in output
