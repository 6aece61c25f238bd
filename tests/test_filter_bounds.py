"""The PCRB of registry filters (analysis.filter_bounds) and their efficiency and consistency
(analysis.filter_quality): closed-form static bounds, and the registry's EKF on data generated
from its own PV model with Gaussian ranges (it must not beat the bound, and come close)."""

import numpy as np
import pandas as pd
import pytest

from synthetic import bursts, run_data, tables_for
from wsnloc.analysis.filter_bounds import bound_model, filter_pcrb, is_bayesian
from wsnloc.analysis.filter_quality import consistency, epoch_quality, grouped_quality, over_time, run_efficiency
from wsnloc.estimators import registry
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.metrics.bounds import toa_crlb
from wsnloc.metrics.tracking import score

FIELD = {"A1": (0.0, 0.0), "A2": (60.0, 0.0), "A3": (60.0, 60.0), "A4": (0.0, 60.0)}
PERIOD = 0.5


def test_static_epoch_bound_is_the_crlb_over_the_number_of_updates():
    """P model with no process noise (F = I, Q = 0), vague prior: after k epoch updates with one
    range per anchor the bound is CRLB / sqrt(k) (the initiator's epoch counts: it starts from its fix)."""
    target = np.array([12.0, 7.0])
    times, ids = bursts(20.0, PERIOD, FIELD)
    data = run_data(tables_for(times, ids, target, FIELD))
    p = registry.get("ekf_p").resolve({"p_sigma_m": 0.0, "initial_sigma_m": 1e4, "range_sigma_m": 0.2,
                                       "update": "epoch"})
    bound = filter_pcrb(data, p)
    position = np.sqrt(bound["pcrb_xx"] + bound["pcrb_yy"]).to_numpy()
    k = np.arange(1, len(bound))              # the grid's last epoch ends after the truth: no information
    expected = toa_crlb(target[None], np.array(list(FIELD.values())), 0.2)[0] / np.sqrt(k)
    np.testing.assert_allclose(position[:-1], expected, rtol=1e-6)
    assert position[-1] == pytest.approx(position[-2], rel=1e-12)


def test_sequential_bound_counts_every_record_and_grows_in_a_gap():
    """Sequential updates, one range per record: the static bound equals that of the epoch
    schedule with the same records; without records the PV bound grows (prediction only)."""
    target = np.array([20.0, 30.0])
    times, ids = bursts(20.0, PERIOD, FIELD)
    keep = (times < 8.0) | (times > 12.0)
    data = run_data(tables_for(times[keep], ids[keep], target, FIELD))
    p = registry.get("ekf").resolve({"update": "sequential"})
    bound = filter_pcrb(data, p)
    position = np.sqrt(bound["pcrb_xx"] + bound["pcrb_yy"]).to_numpy()
    gap = (bound["t"] > 8.0) & (bound["t"] < 12.0)
    assert np.all(np.diff(position[gap.to_numpy()]) > 0)
    static = registry.get("ekf_p").resolve({"p_sigma_m": 0.0, "initial_sigma_m": 1e4, "update": "sequential"})
    epoch = dict(static, update="epoch")
    np.testing.assert_allclose(filter_pcrb(data, static)[["pcrb_xx", "pcrb_yy"]][:-1],   # last: after the truth
                               filter_pcrb(data, epoch)[["pcrb_xx", "pcrb_yy"]][:-1], rtol=1e-9)


def pv_run(rng, seconds: float, accel_sigma: float, range_sigma: float, speed_sigma: float):
    """A PV random-acceleration trajectory sampled every PERIOD and Gaussian ranges to every
    anchor at each sample (one time stamp per burst): data from the filter's own model."""
    F, Q = constant_velocity(PERIOD, accel_sigma)
    n = int(seconds / PERIOD) + 2
    state = np.empty((n, 4))
    state[0] = [30.0, 30.0, *rng.normal(0.0, speed_sigma, 2)]
    chol = np.linalg.cholesky(Q + 1e-15 * np.eye(4))
    for k in range(1, n):
        state[k] = F @ state[k - 1] + chol @ rng.normal(size=4)
    t_samples = np.arange(n) * PERIOD

    def positions(t):
        return np.column_stack([np.interp(t, t_samples, state[:, 0]), np.interp(t, t_samples, state[:, 1])])

    times, ids = bursts(seconds, PERIOD, FIELD)
    return run_data(tables_for(times, ids, positions, FIELD, noise_m=range_sigma, rng=rng, truth_step_s=PERIOD))


@pytest.mark.parametrize("seed", [1, 2])
def test_matched_ekf_rmse_is_at_or_above_its_pcrb_and_close(seed):
    """Registry `ekf` (PV, sequential updates at the ranges' own times) on data from its own
    model at high SNR: Monte Carlo RMSE / sqrt(mean PCRB) over all epochs between 1 and 1.1,
    and its position NEES consistent."""
    rng = np.random.default_rng(seed)
    accel, sigma, speed = 0.1, 0.05, 0.3
    p = registry.get("ekf").resolve({"update": "sequential", "accel_sigma_mps2": accel, "range_sigma_m": sigma,
                                     "initial_speed_sigma_mps": speed, "initial_sigma_m": 1.0, "max_range_m": 1e3,
                                     "self_fit": "none"})    # the matched model: the true noise, one pass
    assert is_bayesian(registry.get("ekf").function) and not is_bayesian(registry.get("minmax").function)
    frames = []
    for r in range(60):
        data = pv_run(rng, 30.0, accel, sigma, speed)
        scored = score(registry.run("ekf", data, p), data.table("truth"))
        frames.append(epoch_quality(scored, filter_pcrb(data, p)).assign(run=f"run-{r}"))
    quality = pd.concat(frames, ignore_index=True)
    series = over_time(quality, PERIOD)
    ratio = np.sqrt((series["rmse"] ** 2).mean() / (series["sqrt_pcrb"] ** 2).mean())
    assert 1.0 <= ratio < 1.1, ratio
    steady = series.iloc[10:]
    assert np.all(steady["rmse"] > 0.75 * steady["sqrt_pcrb"])      # pointwise, 60 runs of sampling noise
    efficiency = np.mean([run_efficiency(g)["efficiency"] for _, g in quality.groupby("run")])
    assert 0.9 < efficiency < 1.15
    tests = consistency(quality, PERIOD, epoch_updates=False)
    assert set(tests) == {"ANEES"} and tests["ANEES"][1].verdict == "consistent"
    assert "PV, white acceleration 0.1 m/s^2" in bound_model(p) and "sigma 0.05 m" in bound_model(p)


def test_overconfident_epoch_filter_is_optimistic_in_nees_and_nis():
    """Ranges 10 x noisier than the filter's R: ANEES and ANIS above their bands."""
    rng = np.random.default_rng(3)
    p = registry.get("ekf_p").resolve({"range_sigma_m": 0.05, "p_sigma_m": 0.0, "update": "epoch"})
    frames = []
    for r in range(10):
        times, ids = bursts(20.0, PERIOD, FIELD)
        data = run_data(tables_for(times, ids, np.array([20.0, 25.0]), FIELD, noise_m=0.5, rng=rng))
        scored = score(registry.run("ekf_p", data, p), data.table("truth"))
        frames.append(epoch_quality(scored, filter_pcrb(data, p)).assign(run=f"run-{r}"))
    tests = consistency(pd.concat(frames, ignore_index=True), PERIOD, epoch_updates=True)
    assert tests["ANEES"][1].verdict == "optimistic" and tests["ANIS"][1].verdict == "optimistic"


def test_grouped_quality_keeps_each_rows_values_and_index():
    """Two filters in one scored frame (interleaved rows, as a paper's run): each group's
    quality rows carry its own times, errors and bound, aligned with the estimates' index."""
    times, ids = bursts(10.0, PERIOD, FIELD)
    data = run_data(tables_for(times, ids, np.array([20.0, 25.0]), FIELD))
    params = {"loose": registry.get("ekf_p").resolve({"range_sigma_m": 1.0}),
              "tight": registry.get("ekf_p").resolve({"range_sigma_m": 0.1})}
    frames = [registry.run("ekf_p", data, p).assign(row=name) for name, p in params.items()]
    scored = score(pd.concat(frames).sort_values("t", kind="stable").reset_index(drop=True), data.table("truth"))
    short = run_data(tables_for(times[times < 6.0], ids[times < 6.0], np.array([20.0, 25.0]), FIELD))
    short_scored = score(registry.run("ekf_p", short, params["tight"]).assign(row="tight"), short.table("truth"))
    (quality, efficiency), (short_quality, _) = grouped_quality([(data, scored), (short, short_scored)], ["row"],
                                                               lambda row: params[row])
    alone = epoch_quality(short_scored, filter_pcrb(short, params["tight"]))    # batched with longer cells
    np.testing.assert_allclose(short_quality["pcrb_m2"], alone["pcrb_m2"], rtol=1e-12)
    assert len(short_quality) < len(quality) / 2
    for name, p in params.items():
        rows = quality[quality["row"] == name]
        np.testing.assert_array_equal(rows["t"], scored.loc[scored["row"] == name, "t"])
        expected = epoch_quality(scored[scored["row"] == name].reset_index(drop=True), filter_pcrb(data, p))
        np.testing.assert_allclose(rows["pcrb_m2"], expected["pcrb_m2"])
        expected_efficiency = run_efficiency(expected)
        for column in ("sqrt_pcrb", "efficiency"):
            assert efficiency.set_index("row").loc[name, column] == pytest.approx(expected_efficiency[column], rel=1e-12)
    loose, tight = (efficiency.set_index("row").loc[n, "sqrt_pcrb"] for n in ("loose", "tight"))
    assert loose > 5 * tight


def test_study_cells_carry_bound_and_consistency_only_for_bayesian_filters():
    """studies.run_cell on synthetic runs: a filter cell gets sqrt_pcrb / efficiency metrics and a
    quality table, whose summary gives ANEES / ANIS rows (chi-square band in band_low / band_high,
    no ci95) and figure panels; a
    solver cell gets neither."""
    from wsnloc.studies import bound_summary, quality_table, results_rows, run_cell

    rng = np.random.default_rng(5)
    runs = {}
    for r in range(3):
        times, ids = bursts(15.0, PERIOD, FIELD)
        runs[f"run-{r}"] = tables_for(times, ids, np.array([20.0, 25.0]), FIELD, noise_m=0.1, rng=rng)
    p = registry.get("ekf").resolve({"range_sigma_m": 0.1, "max_range_m": 1e3})
    estimates, metrics = run_cell("site/walk", "ekf_epoch", "ekf", p, ["all"], runs, None)
    assert (metrics["efficiency"] > 0).all() and (metrics["sqrt_pcrb"] < 0.2).all()
    quality = quality_table(estimates)
    assert len(quality) == len(estimates) and set(quality["run"]) == set(runs)
    rows, bound_panels, consistency_panels = bound_summary("s", [{"label": "site/walk", "cell": "ekf_epoch",
                                                                  "parameters": p}], [quality])
    anees = next(r for r in rows if r["column"] == "anees")
    assert anees["band_low"] < 2.0 < anees["band_high"] and anees["runs"] == 3 and anees["table"] == "all"
    assert anees["ci95_low"] is None and anees["ci95_high"] is None
    assert {r["column"] for r in rows} == {"anees", "anis"} and len(bound_panels) == 1 and len(consistency_panels) == 2
    assert {"sqrt_pcrb", "efficiency"} <= {r["column"] for r in results_rows("s", "ekf_epoch", "site/walk", metrics)}
    solver, solver_metrics = run_cell("site/walk", "minmax", "minmax", registry.get("minmax").resolve({}), ["all"],
                                      runs, None)
    assert quality_table(solver).empty and "efficiency" not in solver_metrics
    assert "efficiency" not in {r["column"] for r in results_rows("s", "minmax", "site/walk", solver_metrics)}


def test_runs_by_epoch_matrix_equals_a_pivot_table_with_inf_nan_and_repeats():
    from wsnloc.analysis.filter_quality import _epoch_index, _runs_by_epoch
    rng = np.random.default_rng(7)
    n = 300
    quality = pd.DataFrame({"run": rng.choice(["run-03", "run-01", "run-02"], n), "t": rng.uniform(0.0, 20.0, n),
                            "nees": rng.choice([1.0, 2.5, np.nan, np.inf], n) * rng.random(n)})
    quality["run"] = quality["run"].astype("str")
    frame = quality.assign(k=_epoch_index(quality["t"], 0.5))     # the former pandas form as reference
    pivot = frame.pivot_table(index="run", columns="k", values="nees", aggfunc="first", dropna=False)
    times = frame.groupby("k")["t"].mean().reindex(pivot.columns)
    table, t = _runs_by_epoch(quality, "nees", 0.5)
    np.testing.assert_array_equal(table, pivot.to_numpy(float))
    np.testing.assert_array_equal(t, times.to_numpy(float))
