"""Statistics, range errors and the path-loss fit on cases with known answers."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from wsnloc import results
from wsnloc.metrics.ranging import fit_path_loss, range_errors
from wsnloc.metrics.stats import MIN_INTERVAL_RUNS, error_summary, mean_ci95, mean_interval


def test_mean_ci95_matches_scipy_t_interval():
    values = np.array([0.41, 0.47, 0.39, 0.52, 0.44, 0.48])
    mean, low, high = mean_ci95(values)
    expected = stats.t.interval(0.95, len(values) - 1, loc=values.mean(), scale=stats.sem(values))
    assert mean == pytest.approx(values.mean())
    assert (low, high) == pytest.approx(expected)


def test_mean_ci95_single_and_missing_values():
    assert np.isnan(mean_ci95([1.0])[1])
    assert mean_ci95([1.0, np.nan, 3.0])[0] == 2.0


def test_mean_interval_real_is_the_student_t_interval():
    values = np.array([0.41, 0.47, 0.39, 0.52, 0.44, 0.48])
    assert mean_interval(values, "real") == pytest.approx(mean_ci95(values))


def test_mean_interval_nonnegative_is_the_t_interval_of_the_log_mean():
    """Delta method: ln m +- t s / (m sqrt(n)), back-transformed; positive for skewed small samples
    whose Student-t interval would reach below 0."""
    values = np.array([0.05, 0.07, 0.06, 2.4, 0.05])
    mean, low, high = mean_interval(values, "nonnegative")
    half = stats.t.ppf(0.975, 4) * values.std(ddof=1) / np.sqrt(5) / values.mean()
    assert (low, high) == pytest.approx((values.mean() * np.exp(-half), values.mean() * np.exp(half)))
    assert mean_ci95(values)[1] < 0 < low < mean < high


def test_mean_interval_share_stays_in_unit_interval():
    values = np.array([1.0, 1.0, 0.2, 1.0, 1.0])
    mean, low, high = mean_interval(values, "share")
    assert mean_ci95(values)[2] > 1.0 and 0.0 < low < mean < high < 1.0
    m, se = values.mean(), stats.sem(values) * stats.t.ppf(0.975, 4)
    logit = np.log(m / (1 - m))
    assert high == pytest.approx(1 / (1 + np.exp(-(logit + se / (m * (1 - m))))))


def test_mean_interval_boundary_and_too_few_runs():
    assert mean_interval([0.0] * 6, "nonnegative") == (0.0, 0.0, 0.0)      # every run the same: [m, m]
    assert mean_interval([1.0] * 6, "share") == (1.0, 1.0, 1.0)
    mean, low, high = mean_interval([0.1, 0.2, 0.3, 0.4][: MIN_INTERVAL_RUNS - 1], "nonnegative")
    assert mean == pytest.approx(0.25) and np.isnan(low) and np.isnan(high)
    with pytest.raises(ValueError, match="outside the nonnegative range"):
        mean_interval([0.1, -0.2, 0.3, 0.4, 0.5], "nonnegative")


def test_results_rows_choose_the_domain_from_the_metric():
    assert [results.metric_domain(m) for m in ("rmse_m", "availability_share", "difference_m (< 0 claimed)",
                                               "P0_dBm", "efficiency_ratio")] == [
        "nonnegative", "share", "real", "real", "nonnegative"]
    row = results.row_over_runs([0.01, 0.02, 0.01, 0.9, 0.02], experiment="e", table="t", row="r", column="c",
                                scenario="s", metric="p95_m")
    assert row["ci95_low"] > 0 and row["band_low"] is None and row["runs"] == 5


def test_error_summary():
    s = error_summary([3.0, -4.0])
    assert s["rmse"] == pytest.approx(np.sqrt(12.5)) and s["max"] == 4.0 and s["median"] == 3.5


def test_path_loss_fit_recovers_noise_free_parameters():
    d = np.linspace(1, 20, 50)
    p = -45.0 - 10 * 2.7 * np.log10(d)
    fit = fit_path_loss(p, d)
    assert (fit["P0_dBm"], fit["n"]) == pytest.approx((-45.0, 2.7)) and fit["sigma_dB"] == pytest.approx(0, abs=1e-9)


def test_path_loss_fit_needs_three_samples():
    assert np.isnan(fit_path_loss([-50, -60], [1, 2])["n"])


def test_range_errors_against_truth(campaign):
    truth = pd.DataFrame({"t": [0.0, 10.0], "x": [2.5, 12.5], "y": [7.5, 7.5]})
    u02 = campaign.anchor_position("U02")
    true_d = np.hypot(7.5 - u02[0], 7.5 - u02[1])
    ranges = pd.DataFrame({"t": [5.0, 5.0, 20.0], "anchor_id": ["U02", "U02", "U02"],
                           "range_m": [true_d + 0.25, 0.0, 3.0], "status": [0, 7, 0], "line": [1, 2, 3]})
    errors = range_errors(ranges, truth, campaign)
    assert len(errors) == 1                       # flagged and out-of-truth records are left out
    assert errors["error_m"].iloc[0] == pytest.approx(0.25) and bool(errors["los"].iloc[0])


def test_results_rows_sharing_their_labels_are_refused(tmp_path):
    labels = dict(experiment="A", table="Claim parts", row="claim", column="Table I: hybrid - TOA",
                  scenario="all", metric="difference_m")
    rows = [results.single_row(-0.57, **labels), results.single_row(-0.66, **labels)]
    with pytest.raises(ValueError, match="r.csv: 2 rows share their labels"):
        results.write(rows, tmp_path / "r.csv")
    results.write([rows[0], results.single_row(-0.66, **{**labels, "column": "Table I: other"})], tmp_path / "r.csv")


def test_results_contract_round_trip(tmp_path):
    rows = [results.row_over_runs([1.0, 2.0, 3.0], experiment="x", table="t", row="r", column="c",
                                  scenario="s", metric="m", paper_value=2.5)]
    results.write(rows, tmp_path / "r.csv")
    back = results.read(tmp_path / "r.csv")
    assert list(back.columns) == results.COLUMNS
    assert back["value"].iloc[0] == 2.0 and back["runs"].iloc[0] == 3 and back["paper_value"].iloc[0] == 2.5
