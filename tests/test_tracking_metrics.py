"""Availability and per-cell metrics (metrics.tracking) against reference implementations:
the interval loop availability was computed with, and a groupby over sub-frames."""

import math

import numpy as np
import pandas as pd
import pytest

from wsnloc.metrics.stats import error_summary
from wsnloc.metrics.tracking import RUN_METRICS, availability, cell_metrics, output_period


def loop_availability(estimates: pd.DataFrame, truth: pd.DataFrame, period: float | None = None) -> float:
    """Reference: the union of (t_i - T, t_i] walked interval by interval with a running reach."""
    if len(truth) < 2:
        return float("nan")
    t0, t1 = float(truth["t"].min()), float(truth["t"].max())
    finite = estimates[np.isfinite(estimates["x"]) & np.isfinite(estimates["y"])]["t"].to_numpy(float)
    period = output_period(estimates["t"].to_numpy(float)) if period is None else period
    if len(finite) == 0 or t1 <= t0:
        return 0.0
    if not np.isfinite(period):
        period = 0.0
    ends = np.clip(np.sort(finite), t0, t1)
    starts = np.clip(ends - period, t0, t1)
    covered, reach = 0.0, t0
    for a, b in zip(starts, ends):
        a = max(a, reach)
        if b > a:
            covered += b - a
            reach = b
    return covered / (t1 - t0)


def groupby_cell_metrics(scored: pd.DataFrame, keys: list[str], truth: pd.DataFrame) -> pd.DataFrame:
    """Reference: one sub-frame per group of `keys`."""
    rows = [{**dict(zip(keys, key)), **error_summary(group["error_m"]), "availability": loop_availability(group, truth),
             "rmse_moving": loop_rmse_moving(group)}
            for key, group in scored.groupby(keys, sort=False)]
    return pd.DataFrame(rows, columns=keys + list(RUN_METRICS) + ["rmse_moving"])


def loop_rmse_moving(group: pd.DataFrame) -> float:
    """Reference: RMSE over the estimates whose true speed from the previous estimate (time order;
    the first takes the second's) is at least 1 cm/s."""
    ordered = group.sort_values("t", kind="stable")
    rows = list(ordered.itertuples())
    if len(rows) < 2:
        return float("nan")
    speeds = []
    for before, after in zip(rows, rows[1:]):
        step = math.hypot(after.true_x - before.true_x, after.true_y - before.true_y)
        speeds.append(step / (after.t - before.t) if after.t > before.t else float("nan"))
    speeds = [speeds[0]] + speeds
    errors = [r.error_m for r, v in zip(rows, speeds) if v >= 0.01 and math.isfinite(r.error_m)]
    return math.sqrt(sum(e * e for e in errors) / len(errors)) if errors else float("nan")


def random_estimates(rng, n: int, sort: bool, spread: float = 1.0) -> pd.DataFrame:
    """n estimates at 0.5 s steps with jitter, some repeated times, some NaN positions,
    times reaching before and after the truth span [0, 0.5 n] (spread)."""
    t = np.arange(n) * 0.5 * spread - 2.0 + rng.normal(0.0, 0.3, n)
    t[rng.random(n) < 0.15] = t[0]                                  # duplicates
    t = np.sort(t) if sort else rng.permutation(t)
    x, y = rng.normal(size=n), rng.normal(size=n)
    x[rng.random(n) < 0.2] = np.nan
    y[rng.random(n) < 0.1] = np.nan
    return pd.DataFrame({"t": t, "x": x, "y": y})


TRUTH = pd.DataFrame({"t": np.linspace(0.0, 30.0, 61)})


@pytest.mark.parametrize("sort", [True, False])
@pytest.mark.parametrize("period", [None, 0.0, 0.5, 1.7, 100.0, np.nan, -1.0])
@pytest.mark.parametrize("seed", range(8))
def test_availability_equals_the_interval_loop(seed, period, sort):
    rng = np.random.default_rng(seed)
    est = random_estimates(rng, int(rng.integers(2, 120)), sort, spread=rng.uniform(0.3, 3.0))
    expected = loop_availability(est, TRUTH, period)
    assert availability(est, TRUTH, period) == pytest.approx(expected, abs=1e-12, nan_ok=True)


@pytest.mark.parametrize("period", [None, 0.0, 1.0, np.nan])
@pytest.mark.parametrize("t", [[5.0], [-3.0], [40.0], [np.nan], [], [2.0, 2.0, 2.0], [3.0, np.nan, 7.0, 1.0]])
def test_availability_edge_cases_equal_the_interval_loop(t, period):
    est = pd.DataFrame({"t": np.array(t, float), "x": 0.0, "y": 0.0})
    for truth in (TRUTH, TRUTH.iloc[:1], pd.DataFrame({"t": [4.0, 4.0]}), TRUTH.iloc[::-1]):
        assert availability(est, truth, period) == pytest.approx(loop_availability(est, truth, period),
                                                                 abs=1e-12, nan_ok=True)


def test_availability_hand_computed_union():
    """T = 2 s on [0, 10] s: estimates at 1, 4, 5 s cover (0, 1] and (2, 4] u (3, 5] = (2, 5];
    one at 14 s is clipped to T1, covering (8, 10]; the one at 8 s has no position.
    Union 1 + 3 + 2 = 6 s of 10 s. With T = 0 nothing is covered."""
    est = pd.DataFrame({"t": [5.0, 1.0, 4.0, 8.0, 14.0], "x": [0.0, 0.0, 0.0, np.nan, 0.0], "y": 0.0})
    truth = pd.DataFrame({"t": [0.0, 10.0]})
    assert availability(est, truth, period=2.0) == pytest.approx(0.6)
    assert availability(est, truth, period=0.0) == 0.0


def scored_run(rng, n: int) -> pd.DataFrame:
    """Scored estimates of several cells (string, integer and missing keys), rows interleaved."""
    est = random_estimates(rng, n, sort=False)
    est["true_x"] = np.where(rng.random(n) < 0.3, 0.0, rng.normal(size=n))   # some at one point: at rest
    est["true_y"] = 0.0
    est["error_m"] = np.abs(rng.normal(size=n))
    est.loc[rng.random(n) < 0.05, "error_m"] = np.nan
    est["method"] = rng.choice(["minmax", "lls", "ekf"], n)
    est["row"] = rng.integers(1, 4, n)
    est["stage"] = pd.array(rng.choice(["raw", "velocity", None], n, p=[0.45, 0.45, 0.1]), dtype="string")
    return est


@pytest.mark.parametrize("keys", [["method"], ["method", "row"], ["stage", "method"], ["row"]])
@pytest.mark.parametrize("seed", range(4))
def test_cell_metrics_equal_the_groupby_over_sub_frames(seed, keys):
    scored = scored_run(np.random.default_rng(seed), 400)
    pd.testing.assert_frame_equal(cell_metrics(scored, keys, TRUTH), groupby_cell_metrics(scored, keys, TRUTH),
                                  check_exact=False, rtol=0, atol=1e-12)


def test_cell_metrics_of_no_estimates_and_of_a_short_truth():
    scored = scored_run(np.random.default_rng(9), 50)
    for frame, truth in ((scored.iloc[:0], TRUTH), (scored, TRUTH.iloc[:1])):
        pd.testing.assert_frame_equal(cell_metrics(frame, ["method"], truth), groupby_cell_metrics(frame, ["method"], truth))


def _former_score(estimates, truth):
    """score as it was: a copy of the estimates with the three columns assigned one by one."""
    from wsnloc.metrics.ranging import truth_at
    position = truth_at(truth, estimates["t"].to_numpy(float))
    out = estimates.copy()
    out["true_x"], out["true_y"] = position[:, 0], position[:, 1]
    out["error_m"] = np.hypot(out["x"] - out["true_x"], out["y"] - out["true_y"])
    return out


@pytest.mark.parametrize("scored_before", [False, True])
def test_score_equals_the_former_copy_assigned_column_by_column(scored_before):
    """Values exactly, dtypes, column order (an existing true_x stays in place), index, attrs."""
    from wsnloc.metrics.tracking import score
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 10, 40))
    est = pd.DataFrame({"t": t, "x": rng.normal(size=40), "y": rng.normal(size=40), "n": np.arange(40),
                        "model": pd.array(rng.choice(["P", "PV"], 40), dtype="str")}, index=np.arange(40) * 3)
    est.loc[est.index[5], "x"] = np.nan
    if scored_before:
        est.insert(1, "true_x", 0.0)
    est.attrs = {"resets": 2, "nested": {"a": [1]}}
    truth = pd.DataFrame({"t": np.linspace(-1, 11, 30), "x": rng.normal(size=30), "y": rng.normal(size=30)})
    got, expected = score(est, truth), _former_score(est, truth)
    pd.testing.assert_frame_equal(got, expected, check_exact=True)
    assert got.attrs == expected.attrs and got.attrs is not est.attrs
    got.attrs["nested"]["a"].append(2)
    assert est.attrs["nested"]["a"] == [1]


def test_rmse_moving_leaves_out_the_epochs_at_rest():
    """Speed claims compare moving epochs: an error made while standing still does not count."""
    t = np.arange(8) * 0.5
    true_x = np.array([0.0, 0.0, 0.0, 0.1, 0.2, 0.3, 0.3, 0.3])   # at rest, moving 0.2 m/s, at rest
    scored = pd.DataFrame({"t": t, "x": true_x, "y": 0.0, "true_x": true_x, "true_y": 0.0,
                           "error_m": [5.0, 5.0, 5.0, 1.0, 1.0, 1.0, 7.0, 7.0], "cell": "a"})
    truth = pd.DataFrame({"t": t, "x": true_x, "y": 0.0})
    metrics = cell_metrics(scored, ["cell"], truth).iloc[0]
    assert metrics["rmse_moving"] == pytest.approx(1.0)          # epochs 3-5 (epoch 6 arrives: 0 m moved)
    assert metrics["rmse"] > 4.0
