"""Three-valued claim verdicts from paired runs, on data whose answer is known."""

import numpy as np
import pytest
from scipy import stats

from wsnloc.metrics.verdicts import (DOES_NOT_HOLD, HOLDS, INCONCLUSIVE, claim, combine,
                                     compare_paired, ordering, paper_value_inside)


def test_paired_difference_interval_matches_scipy_paired_t():
    a = np.array([0.40, 0.46, 0.39, 0.52, 0.44, 0.47])
    b = np.array([0.45, 0.50, 0.41, 0.58, 0.47, 0.52])
    result = compare_paired(a, b, "<", "A - B")
    d = a - b
    expected = stats.t.interval(0.95, len(d) - 1, loc=d.mean(), scale=stats.sem(d))
    assert (result.ci95_low, result.ci95_high) == pytest.approx(expected)
    assert result.mean_diff == pytest.approx(d.mean()) and result.runs == 6
    assert result.verdict == HOLDS
    # the same test from scipy: paired t-test rejects equality at 5%
    assert stats.ttest_rel(a, b).pvalue < 0.05


def test_pairing_decides_where_unpaired_means_would_not():
    # Run-to-run spread (1 m) dwarfs the 0.01 m gap, but A is lower in every run.
    rng = np.random.default_rng(3)
    base = rng.normal(2.0, 1.0, 20)
    a, b = base, base + 0.01 + rng.normal(0.0, 0.001, 20)
    assert compare_paired(a, b, "<").verdict == HOLDS
    assert compare_paired(a, b, ">").verdict == DOES_NOT_HOLD


def test_does_not_hold_when_interval_on_other_side():
    a = np.array([1.0, 1.1, 1.2, 1.05])
    b = a - 0.3 + np.array([0.01, -0.01, 0.02, 0.0])
    result = compare_paired(a, b, "<")
    assert result.verdict == DOES_NOT_HOLD and result.ci95_low > 0


def test_inconclusive_when_interval_contains_zero():
    # issue 15's example: hybrid 0.446 vs TOA 0.445 with run-to-run noise
    a = np.array([0.45, 0.44, 0.47, 0.42, 0.45])
    b = np.array([0.44, 0.46, 0.43, 0.45, 0.445])
    result = compare_paired(a, b, "<", "hybrid - TOA")
    assert result.ci95_low < 0 < result.ci95_high
    assert result.verdict == INCONCLUSIVE
    assert "hybrid - TOA" in result.text() and "5 paired runs: inconclusive" in result.text()


def test_inconclusive_with_fewer_than_two_paired_runs_and_nan_runs_dropped():
    single = compare_paired([1.0], [2.0], "<")
    assert single.verdict == INCONCLUSIVE and single.runs == 1
    dropped = compare_paired([1.0, np.nan, 1.1], [2.0, 2.0, np.nan], "<")
    assert dropped.runs == 1 and dropped.verdict == INCONCLUSIVE


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="side"):
        compare_paired([1, 2], [2, 3], "<=")
    with pytest.raises(ValueError, match="equal lengths"):
        compare_paired([1, 2], [2, 3, 4], "<")
    with pytest.raises(ValueError, match="unknown verdict"):
        combine(["holds", "maybe"])
    with pytest.raises(KeyError, match="C"):
        ordering({"A": [1, 2], "B": [2, 3]}, ["A", "C"])


@pytest.mark.parametrize("parts, expected", [
    ([HOLDS, HOLDS, HOLDS], HOLDS),
    ([HOLDS, INCONCLUSIVE, HOLDS], INCONCLUSIVE),
    ([HOLDS, DOES_NOT_HOLD, INCONCLUSIVE], DOES_NOT_HOLD),
    ([DOES_NOT_HOLD], DOES_NOT_HOLD),
    ([], INCONCLUSIVE),
])
def test_combine(parts, expected):
    assert combine(parts) == expected


def test_every_cell_claim_and_ordering():
    offsets = np.array([0.0, 0.02, -0.01, 0.01])
    cells = [compare_paired(1.0 + offsets, 1.5 + offsets[::-1], "<", f"cell {i}") for i in range(3)]
    every = claim(cells)
    assert every.verdict == HOLDS and len(every.parts) == 3
    assert every.as_dict()["parts"][0]["label"] == "cell 0"
    runs = {"P": 1.0 + offsets, "PV": 0.8 + offsets[::-1], "PVA": 0.6 + offsets}
    assert ordering(runs, ["PVA", "PV", "P"]).verdict == HOLDS
    assert ordering(runs, ["P", "PV", "PVA"]).verdict == DOES_NOT_HOLD
    runs["PV"] = np.array([0.5, 0.9, 0.7, 0.6])          # PV overlaps PVA: inconclusive link
    mixed = ordering(runs, ["PVA", "PV", "P"])
    assert [p.verdict for p in mixed.parts] == [INCONCLUSIVE, HOLDS]
    assert mixed.verdict == INCONCLUSIVE and mixed.text().endswith("=> inconclusive")


def test_paper_value_inside():
    assert paper_value_inside(0.45, 0.40, 0.50)
    assert paper_value_inside("0.40", 0.40, 0.50)
    assert not paper_value_inside(0.39, 0.40, 0.50)
    assert not paper_value_inside(None, 0.40, 0.50)
    assert not paper_value_inside("-", 0.40, 0.50)
    assert not paper_value_inside(0.45, float("nan"), float("nan"))
