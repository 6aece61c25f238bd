"""benchmarks/run.py helpers: Snakemake log parsing and the Monte Carlo slope."""

import sys

import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "benchmarks"))
import run as bench  # noqa: E402  (benchmarks/ is not a package)

LOG = """\
[Sun Nov 22 03:00:00 2026]
rule simulate:
    jobid: 3
[Sun Nov 22 03:00:01 2026]
rule ingest:
    jobid: 2
[Sun Nov 22 03:00:05 2026]
Finished jobid: 3 (Rule: simulate)
[Sun Nov 22 03:00:06 2026]
Finished jobid: 2 (Rule: ingest)
[Sun Nov 22 03:00:06 2026]
localrule report:
    jobid: 1
[Sun Nov 22 03:00:09 2026]
Finished jobid: 1 (Rule: report)
"""


def test_seconds_per_rule_and_jobs_from_the_log():
    assert bench.seconds_per_rule(LOG) == {"ingest": (1, 5.0), "simulate": (1, 5.0), "report": (1, 3.0)}
    assert bench.jobs_run(LOG) == ["simulate", "ingest", "report"]


def test_time_with_one_core_idle_at_the_end():
    """Two jobs overlap until 03:00:05; from then on at most one runs, until 03:00:09."""
    assert bench.last_job_alone_s(LOG) == 4.0


def test_slope_of_the_monte_carlo_cost():
    points = [(5, 12.0, 30.0), (10, 17.0, 40.0), (20, 27.0, 60.0)]
    assert bench.slope(points, 1) == pytest.approx(1.0)
    assert bench.slope(points, 2) == pytest.approx(2.0)
