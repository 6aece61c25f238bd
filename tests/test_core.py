"""The filter core's components (initiator, deleter, updater) and its loops with a stand-in
filter bank: each component does its one job, and the loop only sequences them."""

import numpy as np
import pytest

from synthetic import SQUARE, bursts, run_data, tables_for, walk
from wsnloc.estimators import bayes, core, filter_options, registry
from wsnloc.filters.kalman import ExtendedKalmanFilter
from wsnloc.filters.measurement_models import RangeModel
from wsnloc.metrics.tracking import run_metrics, score

ANCHORS = np.array(list(SQUARE.values()))


def test_deleter_deletes_after_max_coast_s_or_when_lost():
    deleter = core.CoastingDeleter(2.0)
    last = np.array([0.0, 0.0, 0.0, 5.0])
    got = deleter.delete(np.array([2.0, 2.001, 1.0, 5.0]), last, np.array([False, False, True, False]))
    assert got.tolist() == [False, True, True, False]       # exactly 2 s coasts on; lost deletes at once
    assert not deleter.delete(3.0, 1.5, False) and deleter.delete(3.6, 1.5, False)


def test_initiator_needs_a_fix_from_its_window():
    t, ids = bursts(10.0)
    data = run_data(tables_for(t, ids, walk))
    p = registry.get("ekf").resolve({"anchors": "all"})
    source, motion = bayes.measurement_source(data, p), bayes.motion_model(p)
    initiator = core.WindowInitiator(0.5)
    assert initiator.initiate(source, 0.25, motion) is None             # no measurement yet
    x0, P0 = initiator.initiate(source, 1.0, motion)                     # the 4 ranges measured at t = 1 s
    np.testing.assert_allclose(x0[:2], walk(np.array([1.0]))[0], atol=1e-6)
    assert x0.shape == (4,) and np.all(x0[2:] == 0.0)
    np.testing.assert_array_equal(P0, motion.initial_covariance())
    sparse = bayes.measurement_source(run_data(tables_for(t[::3], ids[::3], walk)), p)   # 1-2 anchors per burst
    assert core.WindowInitiator(0.5).initiate(sparse, 2.0, motion) is None          # 2 ranges in (1.5, 2]
    assert core.WindowInitiator(2.0).initiate(sparse, 2.0, motion) is not None      # 4 anchors in (0, 2]


class _Bank:
    """A stand-in filter bank: state = the run index, updated (1 measurement) where `measured`."""

    def __init__(self, measured: np.ndarray):
        self.measured, self.starts = measured, []

    def start(self, i, x0, P0, motion):
        self.starts.append(i)

    def predict(self, rows, F, Q, B, u):
        return []

    def update(self, rows, k):
        used = self.measured[rows, k].astype(int)
        return used, np.where(used > 0, 1.5, np.nan), np.zeros(len(rows), bool)

    def estimates(self, rows):
        return np.tile(np.arange(5.0), (len(rows), 1))


class _Initiator:
    def initiate(self, source, t, motion):
        return (np.zeros(2), np.eye(2)) if source.can_start(t) else None


class _Source:
    def __init__(self, first_fix_s):
        self.first_fix_s = first_fix_s

    def can_start(self, t):
        return t >= self.first_fix_s


def test_epoch_loop_starts_coasts_deletes_and_restarts_per_run():
    """Run 0: fix from 1 s, measurements until 3 s, then none: coasts 2 s (max_coast_s) and is
    deleted at 5.5 s, restarted by the initiator at 6 s. Run 1 (shorter grid): never measured
    after its start, not deleted within its 2.5 s (2 s without an update is within the limit). The start epoch is output with n_meas 0."""
    times = np.arange(1, 15) * 0.5
    measured = np.zeros((2, 14), bool)
    measured[0, :6] = True
    runs = [core.RunInputs(times, _Source(1.0), np.zeros(14, bool), None),
            core.RunInputs(times[:5], _Source(0.5), np.zeros(5, bool), None)]
    motion = registry.get("ekf_p").resolve({})
    out = core.epoch_loop(_Bank(measured), runs, bayes.motion_model(motion), 0.5, _Initiator(),
                          core.CoastingDeleter(2.0))
    (rows0, resets0), (rows1, resets1) = out
    assert resets0 == 1 and resets1 == 0
    np.testing.assert_array_equal(rows0[:, 0], [1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 6.0, 6.5, 7.0])
    np.testing.assert_array_equal(rows0[:, 6], [0, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0])
    assert np.isnan(rows0[0, 7]) and rows0[1, 7] == 1.5 and np.isnan(rows0[5, 7])
    np.testing.assert_array_equal(rows1[:, 0], times[:5])


def test_sequential_loop_deletes_across_a_gap_and_restarts():
    """Ranges stop for 8 s (max_coast_s 3): the track is deleted once, no estimate is output
    in the gap after the coasting limit, and the initiator restarts it after the gap."""
    t, ids = bursts(40.0)
    gap = (t > 15.0) & (t < 23.0)
    data = run_data(tables_for(t[~gap], ids[~gap], walk))
    est = registry.run("ekf", data, {"anchors": "all", "update": "sequential", "max_coast_s": 3.0})
    assert est.attrs["resets"] == 1
    assert not ((est["t"] > 18.0) & (est["t"] < 23.0)).any()
    assert (est["t"] <= 18.0).sum() > 20 and (est["t"] >= 23.0).sum() > 20


def test_withhold_uncertain_leaves_out_rows_past_the_sigma_limit_and_counts_them():
    rows = np.zeros((4, len(core.COLUMNS)))
    rows[:, 0] = [0.0, 1.0, 2.0, 3.0]
    rows[:, 3], rows[:, 5] = [1.0, 8.0, 9.0, np.nan], [1.0, 8.0, 7.5, np.nan]  # sigma sqrt(2), 4, 4.06, NaN
    kept, withheld = core.withhold_uncertain(rows, 4.0)
    assert kept[:, 0].tolist() == [0.0, 1.0, 3.0] and withheld == 1             # NaN covariance: kept
    assert core.withhold_uncertain(rows, 0.0) == (rows, 0)


@pytest.mark.parametrize("name", ["ekf", "tracker", "ekf_rts"])
def test_a_track_coasting_through_a_gap_is_not_output_once_its_sigma_passes_the_limit(name):
    """Ranges stop for 20 s (max_coast_s 10): without the limit the coasting track is output for
    10 s with its sigma growing to metres; with it (the default) the rows past
    max_position_sigma_m are left out and counted, the rows before are the same, the error of the
    kept rows is lower, and the track continues as before after the gap."""
    t, ids = bursts(80.0)
    gap = (t > 30.0) & (t < 50.0)
    tables = tables_for(t[~gap], ids[~gap], walk, noise_m=0.1, rng=np.random.default_rng(2))
    every = registry.run(name, run_data(tables), {"max_position_sigma_m": 0.0})
    limited = registry.run(name, run_data(tables))
    sigma = np.sqrt(every["p_xx"] + every["p_yy"]).to_numpy()
    past = sigma > registry.get(name).resolve({})["max_position_sigma_m"]
    assert past.sum() >= 3 and limited.attrs["withheld"] == past.sum() and every.attrs["withheld"] == 0
    assert np.all((every["t"][past] > 30.0) & (every["t"][past] < 41.0))       # in the gap, while coasting
    np.testing.assert_array_equal(limited["t"], every["t"][~past])
    np.testing.assert_allclose(limited[["x", "y"]], every.loc[~past, ["x", "y"]], atol=1e-12)
    truth = tables["truth"]
    assert run_metrics(score(limited, truth), truth)["rmse"] < run_metrics(score(every, truth), truth)["rmse"]


def test_updater_is_pluggable_and_the_gate_is_counted():
    """A ConfiguredFilter with its own updater (here: drop the first measurement, then the
    plain update) counts what it offered and what it kept; `used` is the kept count."""
    p = registry.get("ekf").resolve({"gate_probability": 0.999})

    def drop_first(filt, z, H, R, hx, S):
        keep = np.arange(len(z)) > 0
        filt.update(z[keep], H=H[keep], R=R[np.ix_(keep, keep)], hx=hx[keep])
        return keep

    counts = filter_options.UpdateCounts()
    make = filter_options.configured_factory(lambda x, P, motion: ExtendedKalmanFilter(x, P, np.eye(4), np.eye(4)),
                                             p, counts, None, updater=drop_first)
    filt = make(np.array([5.0, 5.0, 0.0, 0.0]), np.eye(4), None)
    model = RangeModel(ANCHORS, np.full(4, 0.3))
    model.z = np.hypot(*(ANCHORS - [6.0, 5.0]).T)
    used, nis, lost = core.update_step(filt, model)
    assert (used, lost) == (3, False) and np.isfinite(nis)
    assert (counts.offered, counts.gated) == (4, 1)
    assert counts.attrs()["gated_share"] == pytest.approx(0.25)


def test_the_default_updater_gates_a_wild_range():
    p = registry.get("ekf").resolve({"gate_probability": 0.999})
    filt = ExtendedKalmanFilter(np.array([5.0, 5.0, 0.0, 0.0]), np.eye(4) * 0.01, np.eye(4), np.eye(4))
    model = RangeModel(ANCHORS, np.full(4, 0.3))
    z = np.hypot(*(ANCHORS - [5.0, 5.0]).T) + [0.0, 0.1, 9.0, -0.1]
    keep = filter_options.default_updater(p)(filt, z, model.jacobian(filt.x), model.R(), model.h(filt.x))
    assert keep.tolist() == [True, True, False, True]


@pytest.mark.parametrize("params", [{}, {"update": "sequential", "motion": "p"},
                                    {"update": "sequential", "gate_probability": 0.999, "robust_loss": "huber"},
                                    {"measurements": "hybrid"}])
def test_filterpy_ekf_estimator_equals_ours(params):
    """ekf_filterpy runs filterpy's ExtendedKalmanFilter in the same loops and components as
    ekf: the same estimates to round-off, the same counters."""
    from synthetic import RSS_MODEL
    rng = np.random.default_rng(4)
    t, ids = bursts(40.0)
    data = run_data(tables_for(t, ids, walk, noise_m=0.2, rng=rng, rss_times=np.arange(0.5, 40.0, 0.5)), RSS_MODEL)
    ours = registry.run("ekf", data, dict(params, anchors="all"))
    reference = registry.run("ekf_filterpy", data, dict(params, anchors="all"))
    assert len(ours) > 50 and ours.attrs == reference.attrs
    np.testing.assert_allclose(reference[["x", "y", "p_xx", "p_xy", "p_yy", "nis"]],
                               ours[["x", "y", "p_xx", "p_xy", "p_yy", "nis"]], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", ["tracker", "ekf"])
def test_estimates_do_not_depend_on_the_clock_origin(name):
    """The same run from t = 0 and at Unix times (t + 1.7e9 s, where float64 resolves about 0.24 us):
    the same estimates, relative to the first measurement. The epoch grid used to start 1 ns before
    the first measurement, below that resolution, so the first measurement fell outside the first epoch."""
    t, ids = bursts(30.0)
    tables = tables_for(t, ids, walk, noise_m=0.05, rng=np.random.default_rng(1))
    shifted = {k: (v.assign(t=v["t"] + 1.7e9) if "t" in v else v) for k, v in tables.items()}
    a, b = registry.run(name, run_data(tables)), registry.run(name, run_data(shifted))
    assert len(a) == len(b) > 50
    np.testing.assert_allclose(b["t"] - 1.7e9, a["t"], atol=1e-6)
    np.testing.assert_allclose(b[["x", "y"]], a[["x", "y"]], atol=1e-6)


def test_withheld_are_the_uncertain_estimates_and_those_no_anchor_reaches():
    from wsnloc.estimators.core import withhold_uncertain
    rows = np.array([[0.0, 10.0, 0.0, 1.0, 0.0, 1.0, 1, 1.0],        # sigma sqrt(2) m, 10 m from A
                     [1.0, 10.0, 0.0, 9.0, 0.0, 9.0, 1, 1.0],        # sigma sqrt(18) m: uncertain
                     [2.0, 150.0, 0.0, 1.0, 0.0, 1.0, 1, 1.0]])      # 150 m from A, 130 m from B: unreachable
    anchors = np.array([[0.0, 0.0], [20.0, 0.0]])
    kept, withheld = withhold_uncertain(rows, 4.0, anchors, 100.0)
    assert kept[:, 0].tolist() == [0.0] and withheld == 2
    assert withhold_uncertain(rows, 4.0)[1] == 1 and withhold_uncertain(rows, 0.0, anchors, 200.0)[1] == 0
