"""Issue 28 item 2: the default tracker fits the data at hand with no truth (estimators.self_fit)."""

import numpy as np
import pytest

from synthetic import SQUARE, run_data, tables_for, walk
from wsnloc.estimators import registry, self_fit
from wsnloc.metrics.tracking import run_metrics, score

OFFSETS = {"A1": 0.3, "A2": -0.2, "A3": 0.1, "A4": -0.3}      # per-anchor offsets up to 0.3 m
GAPS = ((80.0, 140.0), (200.0, 260.0))                         # two 60 s gaps


def _run(seed, scale=1.0, offsets=None, noise_m=0.1, duration=340.0, rate_hz=4.0):
    """A walk ranged one anchor at a time (Poisson arrivals), no ranges inside GAPS."""
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.exponential(1.0 / rate_hz, int(duration * rate_hz * 1.5)))
    times = times[times < duration]
    for a, b in GAPS:
        times = times[(times < a) | (times > b)]
    ids = rng.choice(np.array(list(SQUARE), dtype=object), len(times))
    tables = tables_for(times, ids, walk, SQUARE, noise_m=noise_m, rng=rng)
    bias = tables["ranges"]["anchor_id"].map(offsets or {}).fillna(0.0)
    tables["ranges"]["range_m"] = scale * tables["ranges"]["range_m"] + bias
    return tables


def _median(tables, overrides=None):
    estimates = registry.run("tracker", run_data(tables), overrides or {})
    return run_metrics(score(estimates, tables["truth"]), tables["truth"])["median"], estimates


@pytest.mark.parametrize("seed", range(1, 9))
def test_default_tracker_absorbs_a_seven_percent_scale_offsets_and_two_gaps(seed):
    """Acceptance: median within 1.3x of the same run without the errors, gated share < 5%,
    restarts <= gaps; the scale and the offsets found. Seeds 1-8 measured: 1.02, 1.04, 1.11, 1.15,
    1.04, 1.16, 1.15, 1.07x (with the former window projection of range_correction 1.04, 1.11, 1.38,
    1.16, 1.12, 1.01, 1.42, 1.15x: seeds 3 and 7 failed, offsets off by up to 0.14 m)."""
    clean, _ = _median(_run(seed))
    median, estimates = _median(_run(seed, scale=1.07, offsets=OFFSETS))
    assert median <= 1.3 * clean
    assert estimates.attrs["gated_share"] < 0.05
    assert estimates.attrs["resets"] <= len(GAPS)
    assert estimates.attrs["self_fit_range_correction"] == "applied"
    assert estimates.attrs["self_fit_range_scale"] == pytest.approx(1.07, abs=0.02)
    offsets = estimates.attrs["calibrated_offsets_m"]
    assert max(abs(offsets[a] - b) for a, b in OFFSETS.items()) < 0.12
    plain, _ = _median(_run(seed, scale=1.07, offsets=OFFSETS), {"self_fit": "none"})
    assert plain > 1.3 * clean            # without the self-fit the errors matter


@pytest.mark.parametrize("seed", range(1, 9))
def test_given_the_true_sigma_the_tracker_is_within_1_2x_of_the_best_sigma_of_a_grid(seed):
    """Acceptance: range noise 0.1 m; the configured sigma 0.1 (with the default accel) is no worse
    than 1.2x the best of the grid (it was 1.33x-1.36x when the self-fit could only go livelier).
    Seeds 1-8 measured: 1.00x-1.07x."""
    tables = _run(seed)
    grid = {sigma: _median(tables, {"range_sigma_m": sigma})[0] for sigma in (0.05, 0.1, 0.2, 0.3, 0.5)}
    assert grid[0.1] <= 1.2 * min(grid.values())


def test_profile_likelihood_recovers_the_innovation_scale_despite_outliers():
    rng = np.random.default_rng(0)
    S = rng.uniform(0.01, 0.04, 5000)
    y = rng.normal(0.0, np.sqrt(4.0 * S))             # innovations 4x wider than S says
    y[:250] = rng.uniform(-20, 20, 250)               # 5% wild
    _, c = self_fit.profile_likelihood(y, S, 100.0)
    assert c == pytest.approx(4.0, rel=0.1)


def test_sigma_never_collapses_on_a_noise_free_run():
    """The lost branch's failure: the fitted sigma fell to its clamp on clean data and the
    tracker broke. Noise-free ranges: the fitted sigma stays positive and the track exact."""
    tables = _run(4, noise_m=0.0)
    median, estimates = _median(tables)
    assert estimates.attrs["self_fit_range_sigma_m"] >= self_fit.SIGMA_FLOOR_M
    assert median < 0.1 and estimates.attrs["resets"] <= len(GAPS)


def _shifted_run(seed: int) -> dict:
    """_run(seed) with every range 1 m long for 20 s in the middle of the run (30-50 s)."""
    tables = _run(seed)
    r = tables["ranges"]
    tables["ranges"].loc[(r["t"] > 30.0) & (r["t"] < 50.0), "range_m"] += 1.0
    return tables


def test_a_gate_that_rejects_most_measurements_widens_before_it_restarts():
    """Ranges 1 m long for 20 s (a model that stops fitting), without the re-fix: the gate
    widens the covariance and keeps the track (no restart beyond the gaps'), the diagnosis
    counts the widenings."""
    from wsnloc.diagnosis import diagnose_run, report

    tables = _shifted_run(5)
    p = {"self_fit": "none", "range_sigma_m": 0.05, "gate_refix": False}
    estimates = registry.run("tracker", run_data(tables), p)
    assert estimates.attrs["gate_widenings"] >= 1
    assert estimates.attrs["resets"] <= len(GAPS) and estimates.attrs["gate_refixes"] == 0
    text = report(diagnose_run(run_data(tables), estimates, registry.get("tracker").resolve(p)), p)
    assert "widened" in text


@pytest.mark.parametrize("seed", [1, 3, 5])
def test_the_refix_restarts_a_few_times_and_tracks_no_worse_than_the_widening(seed):
    """The same 1 m shift with the re-fix (the default): the restarts beyond the widening run's
    are re-fixes, at most 5 (one every 10 updates over the shift would be 8; measured 1-4), and
    the track over the shift and the 30 s after is no worse (95th percentile of the error;
    measured 0.51-1.00x of the widening run's on these seeds)."""
    tables = _shifted_run(seed)
    p = {"self_fit": "none", "range_sigma_m": 0.05}
    widened = registry.run("tracker", run_data(tables), dict(p, gate_refix=False))
    refixed = registry.run("tracker", run_data(tables), p)
    assert 1 <= refixed.attrs["gate_refixes"] <= 5
    assert refixed.attrs["resets"] - refixed.attrs["gate_refixes"] <= widened.attrs["resets"]

    def p95(estimates):
        scored = score(estimates, tables["truth"])
        return np.percentile(scored["error_m"][(scored["t"] > 30.0) & (scored["t"] < 80.0)], 95)
    assert p95(refixed) <= 1.05 * p95(widened)


@pytest.mark.parametrize("seed", range(1, 7))
def test_the_self_fit_does_not_hurt_a_run_without_errors(seed):
    """Nothing to fit: the self-fitted track stays within 1.15x of the configured single pass (seeds 1-6
    measured: 1.00x-1.11x; the range correction is not supported on any)."""
    tables = _run(seed)
    fitted, _ = _median(tables)
    plain, _ = _median(tables, {"self_fit": "none"})
    assert fitted <= 1.15 * plain


def test_a_range_correction_the_innovations_do_not_support_is_not_applied():
    """Four anchors clustered within 2.6 m, the target 5-15 m away, ranges one anchor at a time,
    no range error: a common scale and offsets trade off against the target's distance and cannot
    be told apart; the likelihood-ratio test on the innovations leaves the ranges as measured
    (applied, the spurious correction made the median 1.1x worse than none on this run)."""
    cluster = {"A1": (2.2, 0.2), "A2": (-0.4, -0.5), "A3": (0.7, -0.9), "A4": (0.0, 0.9)}
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.exponential(0.25, 1500))
    times = times[times < 300.0]
    ids = rng.choice(np.array(list(cluster), dtype=object), len(times))
    tables = tables_for(times, ids, lambda t: walk(t) - 1.0, cluster, noise_m=0.1, rng=rng)
    median, estimates = _median(tables)
    plain, _ = _median(tables, {"self_fit": "none"})
    assert estimates.attrs["self_fit_range_correction"] == "not supported"
    assert estimates.attrs["self_fit_range_ll_gain"] < estimates.attrs["self_fit_range_ll_penalty"]
    assert estimates.attrs["calibrated_scale"] == 1.0 and not estimates.attrs["calibrated_offsets_m"]
    assert median <= 1.05 * plain


def _offset_case(track_error):
    """Noise-free ranges one anchor at a time with OFFSETS, and a track = truth + track_error(t) (m)."""
    tables = _run(2, offsets=OFFSETS, noise_m=0.0)
    truth = tables["truth"]
    track = truth[["t", "x", "y"]].copy()
    track[["x", "y"]] += track_error(track["t"].to_numpy())
    p = registry.get("tracker").resolve({})
    return run_data(tables), track, p


def test_range_correction_recovers_offsets_exactly_against_the_true_track():
    """Closed form: against the true track e_i = b_a exactly, and dx = 0 fits it."""
    data, track, p = _offset_case(lambda t: np.zeros((len(t), 2)))
    fit = self_fit.range_correction(data, track, p, 1.0)
    assert fit["offsets_m"] == pytest.approx(OFFSETS, abs=1e-6)


def test_range_correction_undoes_a_smooth_error_of_the_track():
    """A track 0.3 m off along a slow curve (as a filter that absorbed biases or lags): the offsets
    are found to 1 cm, where each anchor's median residual against that track is off by more."""
    def error(t):
        return 0.3 * np.column_stack([np.sin(t / 15.0), np.cos(t / 20.0)])
    data, track, p = _offset_case(error)
    fit = self_fit.range_correction(data, track, p, 1.0)
    assert max(abs(fit["offsets_m"][a] - b) for a, b in OFFSETS.items()) < 0.01
    from wsnloc.diagnosis import track_distances
    samples = track_distances(data, track, p)
    medians = (samples["range_m"] - samples["true_distance_m"]).groupby(samples["anchor_id"]).median()
    assert max(abs(medians[a] - b) for a, b in OFFSETS.items()) > 0.05


def test_smooth_error_fit_schur_complement_matches_least_squares_of_the_stacked_system():
    """G^-1 g (the parameters' Schur complement) equals the parameter part of the full least-squares
    solution of the stacked whitened system (residual rows, second differences, weak prior) by
    numpy.linalg.lstsq."""
    rng = np.random.default_rng(1)
    n, q, sigma, accel = 60, 3, 0.1, 0.5
    t = np.sort(rng.uniform(0.0, 7.5, n))
    t -= t[0]                                          # the fit counts time from the first residual
    X = np.eye(q)[rng.integers(0, q, n)]
    gradient = rng.normal(size=(n, 2))
    error = rng.normal(0.0, 0.3, n)
    G, g = self_fit.smooth_error_fit(t, X, gradient, error, sigma, accel)
    K = int(np.floor(t.max() / self_fit.KNOT_S)) + 2
    k = np.minimum(np.floor(t / self_fit.KNOT_S).astype(int), K - 2)
    w = t / self_fit.KNOT_S - k
    A = np.zeros((n + 2 * (K - 2) + 2 * K, q + 2 * K))
    A[:n, :q] = X / sigma
    for i in range(n):
        for axis in range(2):
            A[i, q + 2 * k[i] + axis] = (1 - w[i]) * gradient[i, axis] / sigma
            A[i, q + 2 * (k[i] + 1) + axis] = w[i] * gradient[i, axis] / sigma
    sd = accel * np.sqrt(2.0 / 3.0 * self_fit.KNOT_S**3)
    for j in range(K - 2):
        for axis in range(2):
            A[n + 2 * j + axis, q + 2 * j + axis: q + 2 * j + axis + 5: 2] = np.array([1.0, -2.0, 1.0]) / sd
    A[n + 2 * (K - 2):, q:] = np.eye(2 * K) / self_fit.CORRECTION_PRIOR_M
    b = np.r_[error / sigma, np.zeros(A.shape[0] - n)]
    full = np.linalg.lstsq(A, b, rcond=None)[0]
    assert np.linalg.solve(G, g) == pytest.approx(full[:q], abs=1e-8)


CORRIDOR = {"K1": (0.0, 0.2), "K2": (10.0, 2.8), "K3": (20.0, 0.1), "K4": (30.0, 2.9), "K5": (40.0, 0.3),
            "K6": (50.0, 2.7), "K7": (60.0, 0.2)}


def _corridor_run(seed):
    """Seven anchors nearly in a line along a 60 m corridor, synchronous rounds at 4 Hz for 300 s,
    a 5% range scale error and per-anchor offsets up to 0.4 m, 0.05 m noise."""
    def path(t):
        t = np.asarray(t, dtype=float)
        return np.column_stack([30.0 + 26.0 * np.sin(2 * np.pi * t / 120.0), 1.5 + 0.4 * np.sin(2 * np.pi * t / 37.0)])
    rng = np.random.default_rng(seed)
    epochs = np.arange(0.5, 300.0, 0.25)
    ids = np.tile(np.array(list(CORRIDOR), dtype=object), len(epochs))
    tables = tables_for(np.repeat(epochs, len(CORRIDOR)), ids, path, CORRIDOR, noise_m=0.05, rng=rng)
    offsets = dict(zip(CORRIDOR, rng.uniform(-0.4, 0.4, len(CORRIDOR))))
    tables["ranges"]["range_m"] = 1.05 * tables["ranges"]["range_m"] + tables["ranges"]["anchor_id"].map(offsets)
    return tables


def test_where_the_correction_is_rejected_the_noise_is_chosen_on_the_ranges_as_measured(monkeypatch):
    """The output pass then reads the ranges as measured, so its noise is the one the self-fit picks
    when no correction is proposed at all (measured: with the noise chosen on the corrected ranges it
    ran the livelier candidate, ratio factor 6, where the ranges as measured call for 1/6)."""
    monkeypatch.setattr(self_fit, "_scale_only", lambda *args: None)      # the ranges as measured, not the scale alone
    tables = _corridor_run(1)
    _, estimates = _median(tables)
    assert estimates.attrs["self_fit_range_correction"] == "not supported"
    monkeypatch.setattr(self_fit, "range_correction", lambda *args: None)
    _, uncorrected = _median(tables)
    for key in ("self_fit_ratio_factor", "self_fit_run_sigma_m", "self_fit_run_accel_mps2"):
        assert estimates.attrs[key] == pytest.approx(uncorrected.attrs[key])


@pytest.mark.parametrize("seed", [1, 3])
def test_where_the_offsets_are_not_constant_the_scale_alone_is_kept(monkeypatch, seed):
    """The corridor (anchors nearly in a line, 5% scale error): the local test rejects the offsets,
    and with them the scale went (measured median 3.07 / 2.88 m); the scale alone, tested on the
    segment against the ranges as measured, is kept (measured 0.50 / 0.23 m)."""
    tables = _corridor_run(seed)
    median, estimates = _median(tables)
    assert estimates.attrs["self_fit_range_correction"] == "applied, scale only (offsets not constant)"
    assert estimates.attrs["self_fit_range_local_gain"] > estimates.attrs["self_fit_range_local_penalty"]
    assert estimates.attrs["self_fit_range_scale"] == pytest.approx(1.05, abs=0.01)
    assert estimates.attrs["calibrated_scale"] == estimates.attrs["self_fit_range_scale"]
    assert not estimates.attrs["calibrated_offsets_m"]
    monkeypatch.setattr(self_fit, "_scale_only", lambda *args: None)
    without, _ = _median(tables)
    assert median < 0.3 * without


def test_a_scale_the_segment_does_not_support_is_not_kept_alone():
    """_scale_only on a run without a scale error, offered a wrong scale (1.05): the corrected ranges
    lower the likelihood against the ranges as measured, so no scale-only model; none either for a
    scale of exactly 1 (nothing to correct), on range differences, for the P model (its lag) or with
    the NLOS-aware noise (the scale there is the NLOS excess's trend with distance)."""
    from wsnloc.estimators import bayes

    tables = _run(1)
    p = registry.get("tracker").resolve({})
    q = dict(p, self_fit="none")
    part = self_fit.segment(run_data(tables), q, self_fit.SEARCH_SHARE)
    span = 2.0 * p["max_range_m"]
    as_measured = self_fit._score(bayes._fit_pass, part, dict(q, range_calibration="none"), span)
    candidate = dict(q, range_calibration="other_run")
    model = {"scale": 1.05, "offsets_m": {"A1": 0.2}, "parameters": 5, "source": "injected"}
    assert self_fit._scale_only(bayes._fit_pass, part, candidate, model, as_measured, p, span) is None
    near = dict(model, scale=1.0)
    assert self_fit._scale_only(bayes._fit_pass, part, candidate, near, as_measured, p, span) is None
    tdoa = dict(p, measurements="tdoa")
    assert self_fit._scale_only(bayes._fit_pass, part, candidate, model, as_measured, tdoa, span) is None
    random_walk = dict(p, motion="p")
    assert self_fit._scale_only(bayes._fit_pass, part, candidate, model, as_measured, random_walk, span) is None
    walls = dict(p, range_sigma_per_wall_m=0.3)
    assert self_fit._scale_only(bayes._fit_pass, part, candidate, model, as_measured, walls, span) is None
