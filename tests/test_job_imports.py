"""Job start-up: the workflow scripts import only what their job uses (each Snakemake `script:`
job is a fresh interpreter that runs its script's module-level imports first)."""

import subprocess
import sys

import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "benchmarks"))
from run import script_imports  # noqa: E402  (benchmarks/ is not a package)

HEAVY = ("scipy.signal", "scipy.stats", "scipy.linalg", "scipy.special", "scipy.optimize", "matplotlib")
# Jobs whose start-up loads none of HEAVY (ingest filters the IMU in passing, with the numpy
# polyphase FIR of wsnloc.signal.resample, not scipy.signal; ingest loads matplotlib only at
# the end, when it writes the scenario's data summary and its figures; each paper's one job
# draws its figures; the report embeds the figures other jobs drew, the floor plans included).
LIGHT_JOBS = ("simulate", "ingest", "study_scenario", "report")


@pytest.mark.parametrize("job", LIGHT_JOBS)
def test_light_jobs_do_not_import_scipy_or_matplotlib(job):
    code = "; ".join(script_imports([ROOT / "workflow" / "scripts" / f"{job}.py"]))
    probe = f"{code}\nimport sys\nprint(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "", f"{job}.py loads {result.stdout.strip()} at start-up"
