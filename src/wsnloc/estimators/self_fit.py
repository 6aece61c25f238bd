"""Two-pass self-fit (offline, no truth): the noise and the range errors of the run at hand.

Real data break a filter's assumptions in a few common ways: the range noise is not the
configured one, the motion is livelier or calmer than the process noise says, the ranges carry
a common scale error and per-anchor offsets. `self_fit: two_pass` (the default of `tracker` and of every
Bayesian filter and smoother of the registry: ekf, ukf, pf, ekf_filterpy, ekf_rts, ukf_rts)
learns them from the run itself, with gated EKF passes (estimators.bayes._fit_pass); the
estimator's own filter or smoother then runs once with the fitted values (`output`):

1. **Range scale and per-anchor offsets** (ranges, >= 4 anchors ranged, no configured or donor
   calibration, which wins): a first pass with the state augmented by a common range scale
   (estimators.self_calibration; observable while the target moves among >= 4 anchors); then
   the per-anchor offsets against that pass's track (range_correction: least squares jointly
   with the track's own smooth error, undoing what the track absorbed). The ranges are corrected
   (estimators.range_calibration) for the next passes. On range differences (>= 4 anchors in
   the pairs) the same in TDOA form (tdoa_correction: scale and offset differences b_a - b_ref,
   a pair's bias, against a plain first pass's track, refitted once on the corrected track);
   step 4 tests it as it tests the range correction, the corrected differences z' = (z - b_a +
   b_ref) / s paying n log s (the density of z).
2. **Noise, by maximum likelihood of the innovations.** Three candidates, the configured
   (range_sigma_m, accel_sigma_mps2; p_sigma_m in its place for the P model), a calmer (sigma x 2,
   accel / 3) and a livelier one (sigma / 2, accel x 3): the ratio accel / sigma, which sets the
   filter's gain, x 1/6, 1 and 6.
   Each runs on the central SEARCH_SHARE of the run's measurements (segment(); a sub-run, so the
   search costs a fraction of a pass) and records every innovation y_i = z_i - h_i(x-) and its
   variance S_i = (H P- H' + R)_ii, gated ones included. Scaling Q and R together by c leaves a
   linear filter's track unchanged and scales every S_i by c, so per candidate the likelihood is
   profiled over c:
       L(c) = sum_i log[(1 - eps) N(y_i; 0, c S_i) + eps / span],
   a Gaussian with a uniform outlier component (eps = OUTLIER_SHARE over span = 2 max_range_m:
   reflections and NLOS ranges do not decide the noise), c on a log grid (CLAMP).
3. **The ratio**: the best candidate's, or, when the middle (configured) one is the best, the
   maximum of the parabola through the three max_c L(c) against log(ratio) (refine()); sigma
   and accel interpolated in log between the candidates. One full pass with them is the output.
   The candidates' absolute sigma is kept for the run (not scaled by c*): the gate then keeps
   the candidate's width, and on real ranges with NLOS errors the Gaussian core's c* is too
   narrow a gate. attrs `self_fit_*`: the ratio factor, the sigma and accel the pass ran with
   (`self_fit_run_*`) and the fitted noise range_sigma_m sqrt(c*) (floored at SIGMA_FLOOR_M) and
   accel sqrt(c*), and the range scale. Because the likelihood is that of the innovations, which
   carry the state's own uncertainty H P H', the fitted sigma does not collapse onto the track
   the way residuals against the filter's own output do.
4. **Is the range correction supported?** A common scale and per-anchor offsets are separable
   from the position only with enough geometry: with anchors clustered a few metres apart and
   the target further away, a scale, a common offset and the target's distance trade off, and
   the fit of step 1 returns a correction the data do not support (on a real run thinned to one
   range per round it made the RMSE 2.7x worse).
   So the best candidate also runs on the segment with the ranges as measured, and the correction
   is kept only when it raises max_c L(c) by more than the BIC penalty of its k free parameters,
   k / 2 ln(n_innovations), k = 1 + n_anchors on ranges (the scale and each anchor's offset) and
   n_anchors - 1 (+ 1 where the scale was fitted, not held at 1) on range differences, whose
   offsets are defined up to a common constant (the gauge anchor's is 0) (a likelihood-ratio test: the likelihood of nested
   models, the extra parameters paid for; the corrected ranges (r - b) / s pay n log s, the
   density of r); else the output pass reads the ranges as measured.
   A correction is constant over the run; biases that change along the path (NLOS behind walls)
   are not, yet a constant fitted to them can pass that test: on simulated newcom/tdoa run 1
   anchors behind walls carry NLOS biases of 0.3-3.4 m that change along the path, the constant
   offsets fitted to them (1-2 m) turn gated differences into inliers and raise the likelihood by
   495 against a penalty of 38, and make the RMSE 1.01 m against 0.235 m without them. So the
   correction is also tested against one fitted on the segment alone (the same fit against the
   part of the track it was fitted on that spans the segment: what the segment calls for): it is
   kept only when that local correction does not raise max_c L(c) over the constant one by more
   than the BIC penalty of its own parameters (k_local / 2 ln n; nested in the sense that a
   constant over the run is a local fit that happens to hold everywhere). On that run 82 > 38: not
   applied, RMSE 0.257 m with the noise chosen on the corrected differences (0.321 m now, below).
   A constant offset passes (the local fit finds the same offsets, gain about 0). On ranges
   ranged one at a time at a few Hz the segment holds ~100 ranges, too few for the local fit to tell a 1 m bias on part of the path from a constant (measured: a
   synthetic walk with two anchors 1 m long on half the square, local gain 1-10 against 12; the
   correction still applied there).
   Where the local test rejects the offsets of a correction that passed the first test, the
   scale alone (the augmented pass's, which is estimated apart from the offsets) is tested as the
   first test tests the correction, one parameter paid for (_scale_only), and kept if it passes:
   a real scale error (clock drift, a wrong speed of light in the firmware) is not lost with
   offsets that change along the path. Measured (2026-12-07, `tracker` with no flags, against the
   same code without this step): the corridor above 3.07 / 2.88 m median -> 0.50 / 0.23 m (seeds
   1, 3); a simulated outdoor walk (4 beacons 60 m apart, one range at a time at 3 Hz, 0.3 m
   noise, 10% NLOS, a 7% scale, 17-97 s gaps) where the local test rejected (1 seed of 12)
   5.35 -> 0.48 m; on the 21 simulated Newcom++ range runs the step applied on 13, RMSE lower on
   11 (by up to 26%) and higher on 2 (+1.5%, +29%: variable run 5, 0.252 -> 0.325 m), by
   compensating part of their NLOS excess rather than a scale error (_scale_only); the shared
   cucudasluv cases unchanged (no local rejection there).
   attrs `self_fit_range_correction` (applied / applied, scale only / not supported), `self_fit_range_ll_gain`,
   `self_fit_range_ll_penalty`, `self_fit_range_local_gain`, `self_fit_range_local_penalty`.
   Where either test rejects the correction (and the scale alone is not kept), the noise is
   chosen again on the segment with the ranges as measured (with the scale alone where it is
   kept), which the output pass then reads (_rescore: the best candidate's score
   there is known, the middle candidate is scored, and the far edge only where the middle one
   beats the known one: the likelihood is taken as unimodal in the ratio). Chosen on the
   corrected ranges and then run on the ranges as measured, it had picked the livelier candidate
   for ranges whose uncorrected errors call for the calmer one: on a simulated corridor (7
   anchors nearly in a line, synchronous rounds, a 5% scale error and offsets) 2.4-2.9 m RMSE now
   against 3.5-4.5 m, on 2 of 15 simulated Newcom++ runs 0.252 / 0.287 m against 0.352 / 0.370 m;
   the shared cucudasluv cases unchanged. The likelihood is not the RMSE: on simulated
   newcom/tdoa run 1 (above) the differences as measured prefer the calmer candidate, whose track
   lags (0.321 m against 0.257 m with the noise chosen on the corrected differences).

Why three candidates: with only the configured one and a livelier one, a configured sigma
smaller than the default (e.g. the true 0.1 m with the default accel) could never go calmer
and tracked the noise (1.33x the best sigma of a grid on a synthetic walk); now the outcome
hardly depends on where the configured values start.

Cost: one augmented pass (step 1; about 1.2x a plain pass: the calibration columns), four passes
on 12% of the run (five where the correction passes the first test; one or two more where it is
rejected: the noise scored again as measured or with the scale alone, itself scored once where
the local test rejects), one full pass and the fits
(the offsets' sparse least squares: about 0.01 s a fit on a real case; the likelihoods and
innovations about 0.03 s): the self-fitted run costs 2.6-3.0x one plain pass in CPU time on the
shared real cases (best of 3, 2026-12-05; 2.7-3.1x before the measurement models of the
candidates shared their geometry and the passes stopped leaving an object per update for the
garbage collector; benchmarks/realdata.py prints it per case), the tuning alone (without the
output pass) 1.6-2.0x; on a synthetic run ranged one anchor at a time (340 s at 4 Hz,
tests/test_self_fit.py) 2.9-3.0x without range errors and 3.2-3.3x where the correction is
applied (2026-12-07, seeds 1-4, minimum of 30 runs each, alternating with the previous code, which
took 3.2-3.5x there: the segment's variants without and with the local correction now share its
cache; one of those passes is the output pass; seven passes' fixed costs weigh more on a short
run); on
range differences two full passes in step 1 (the offsets are fitted twice). For the UKF,
particle filter and smoothers the fitting passes are EKF passes, so the overhead is that of
the EKF's (about 1.7 EKF passes) on top of their own single pass.
Online (live) use has no second pass: `range_self_calibration` (state augmentation) and the
gate's widening and re-fix (filter_options) adapt as the data come.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from wsnloc.estimators import range_calibration
from wsnloc.filters.measurement_models import TdoaModel
from wsnloc.metrics.stats import robust_sigma

MODES = ("none", "two_pass")
# noise candidates (sigma factor, accel factor): calmer, configured, livelier; the ratio accel / sigma
# x 1/6, 1, 6 (the process-to-measurement noise variance ratio x 1/36, 1, 36)
CANDIDATES = ((2.0, 1.0 / 3.0), (1.0, 1.0), (0.5, 3.0))
SEARCH_SHARE = 0.12                    # the candidates are scored on the central 12% of the measurements
MEASUREMENT_TABLES = ("ranges", "rss", "tdoa")
PROCESS_NOISE = ("accel_sigma_mps2", "p_sigma_m")   # the process noise the candidates scale: PV / PVA, P (random walk)
FITTED_NOISE_KEYS = {"accel_sigma_mps2": ("self_fit_run_accel_mps2", "self_fit_accel_sigma_mps2"),
                     "p_sigma_m": ("self_fit_run_p_sigma_m", "self_fit_p_sigma_m")}
OUTLIER_SHARE = 0.05                   # eps of the uniform outlier component
CLAMP = (0.01, 100.0)                  # c* searched on a log grid in this range
GRID = np.exp(np.linspace(np.log(CLAMP[0]), np.log(CLAMP[1]), 161))
SIGMA_FLOOR_M = 0.01
MIN_INNOVATIONS = 50
MIN_ANCHORS_FOR_OFFSETS = 4
WINDOW_S = 1.0                         # windows of the TDOA offsets' projection fit
MIN_SPREAD = 0.5                       # smallest singular value of a window's gradient matrix H
KNOT_S = 1.0                           # s: knots of the track's error in the offsets' fit (smooth_error_fit); the
                                       # filter's error changes over seconds (0.5 s measured alike on the seeds)
CORRECTION_PRIOR_M = 10.0              # m: weak prior of the track's error at a knot (smooth_error_fit)
ACCEL_FLOOR = 1e-3                     # m/s^2: a zero accel_sigma_mps2 in the offsets' fit
MAX_CONDITION = 1e3
OUTLIER_SIGMAS = 4.0
MIN_SCALE_ERROR = 0.02                 # a TDOA scale fit within 2% of 1 is kept at 1 (track lag aliases into it)
TDOA_FITS = 2                          # TDOA scale and offsets: fitted on the plain track, then refitted on the corrected one


def profile_likelihood(y: np.ndarray, S: np.ndarray, span: float) -> tuple[float, float]:
    """(max_c L(c), c*) of innovations y with variances S (module docstring, step 1)."""
    u = (y**2 / S)[None, :]
    c = GRID[:, None]
    gauss = np.exp(-0.5 * u / c) / np.sqrt(2.0 * np.pi * c * S[None, :])
    ll = np.log((1.0 - OUTLIER_SHARE) * gauss + OUTLIER_SHARE / span).sum(axis=1)
    best = int(np.argmax(ll))
    return float(ll[best]), float(GRID[best])


def _anchors_ranged(data, p) -> int:
    ranges = data.usable_ranges(p["preliminary_filter"], p["max_range_m"])
    return int(ranges["anchor_id"].isin(data.members(p["anchors"])).groupby(ranges["anchor_id"]).any().sum())


def range_correction(data, estimates: pd.DataFrame, p: dict, scale: float) -> dict | None:
    """Per-anchor offsets b_a of r = s d + b_a against the track's distances d, with the scale s the
    first pass estimated online (state augmentation, estimators.self_calibration: a scale is
    observable among >= 4 anchors, while against the filter's own track it is mostly absorbed);
    None with too few ranges.

    The residuals e_i = r_i - s d_i are fitted jointly with the track's own error (smooth_error_fit):
        e_i = b_a(i) + s u_i . dx(t_i) + n_i,
    u_i the unit vector from anchor a(i) to the track at t_i (the gradient of d), n_i ~ N(0, sigma^2)
    with sigma the residuals' normalised MAD about their anchor's median. Where the offsets'
    information G is ill-conditioned (condition number above MAX_CONDITION: offsets not separable
    from the position, e.g. anchors seen in nearly one direction) the median residual per anchor.
    Residuals further than OUTLIER_SIGMAS normalised MADs from their anchor's median (reflections,
    NLOS) are left out first."""
    from wsnloc.diagnosis import track_distances

    samples = track_distances(data, estimates, p)
    if samples is None:
        return None
    ids = samples["anchor_id"].astype(str).to_numpy()
    distance = samples["true_distance_m"].to_numpy(float)
    error = samples["range_m"].to_numpy(float) - scale * distance
    anchors, column = np.unique(ids, return_inverse=True)
    centre = pd.Series(error).groupby(column).transform("median").to_numpy()
    sigma = max(robust_sigma(error - centre), SIGMA_FLOOR_M)
    inlier = np.abs(error - centre) <= OUTLIER_SIGMAS * sigma
    samples, error, column, distance = samples[inlier], error[inlier], column[inlier], distance[inlier]
    unit = (samples[["true_x", "true_y"]].to_numpy(float) - data.positions(anchors)[column]) \
        / np.maximum(distance, 1e-3)[:, None]
    G, g = smooth_error_fit(samples["t"].to_numpy(float), np.eye(len(anchors))[column], scale * unit, error,
                            sigma, p["accel_sigma_mps2"])
    if np.linalg.cond(G) < MAX_CONDITION:
        offsets = np.linalg.solve(G, g)
    else:
        offsets = pd.Series(error).groupby(column).median().to_numpy()
    return {"scale": scale, "offsets_m": {str(a): float(b) for a, b in zip(anchors, offsets)},
            "parameters": 1 + len(anchors), "source": "self-fitted on the run (two-pass)"}


def smooth_error_fit(t: np.ndarray, X: np.ndarray, gradient: np.ndarray, error: np.ndarray, sigma: float,
                     accel_sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """The normal equations G theta = g of constant measurement-error parameters theta (q,) fitted
    jointly with the error of the track the residuals were computed against.

    A track computed from biased measurements has moved to absorb part of the biases, smoothly in
    time as a filter moves. So the residuals e_i against it (m; measured at t_i, s) are modelled as
        e_i = X_i theta + gradient_i . dx(t_i) + n_i,   n_i ~ N(0, sigma^2),
    with dx(t) = true position - track (m, 2-D), linear between knots tau_k KNOT_S apart, and
    gradient_i the measurement's gradient in position at the track (n, 2). Prior of dx: white
    acceleration of density q = accel_sigma^2 (the configured motion model's), as second
    differences per axis  dx_k-1 - 2 dx_k + dx_k+1 ~ N(0, 2/3 q KNOT_S^3)  (the integrated Wiener
    process's; the overlap of consecutive ones neglected), and dx_k ~ N(0, CORRECTION_PRIOR_M^2)
    (keeps knots no measurement sees determined). Linear least squares in (theta, dx): with the
    normal matrix in blocks N_tt, N_tx, N_xx (N_xx sparse, banded) and right-hand side (g_t, g_x),
    theta's Schur complement  G = N_tt - N_tx N_xx^-1 N_xt,  g = g_t - N_tx N_xx^-1 g_x.
    A zero accel_sigma is taken as ACCEL_FLOOR (a stiff prior: dx linear in time).
    (It replaced a projection through 1 s windows, each window's position free: on ranges one
    anchor at a time a window holds 2-4 ranges and kept one or two of them for the offsets, whose
    errors reached 0.14 m on tests/test_self_fit.py's seeds 3 and 7; at most 0.10 m on seeds 1-8 now.)"""
    import scipy.sparse as sp                     # here, not at module level: the jobs that do not
    from scipy.sparse.linalg import splu          # self-fit start without scipy.linalg (tests/test_job_imports.py)

    t = t - t.min()
    n, K = len(t), int(np.floor(t.max() / KNOT_S)) + 2
    k = np.minimum(np.floor(t / KNOT_S).astype(int), K - 2)
    w = t / KNOT_S - k                                    # linear interpolation weight of knot k + 1
    columns = np.column_stack([2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3])
    values = np.column_stack([(1 - w) * gradient[:, 0], (1 - w) * gradient[:, 1], w * gradient[:, 0], w * gradient[:, 1]])
    B = sp.csr_matrix((values.ravel(), (np.repeat(np.arange(n), 4), columns.ravel())), shape=(n, 2 * K))
    second = sp.kron(sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(K - 2, K)), sp.identity(2)) \
        / (max(accel_sigma, ACCEL_FLOOR) * np.sqrt(2.0 / 3.0 * KNOT_S**3))
    N_xx = ((B.T @ B) / sigma**2 + second.T @ second + sp.identity(2 * K) / CORRECTION_PRIOR_M**2).tocsc()
    N_xt = np.asarray(B.T @ X) / sigma**2
    solve = splu(N_xx).solve
    G = X.T @ X / sigma**2 - N_xt.T @ solve(N_xt)
    g = X.T @ error / sigma**2 - N_xt.T @ solve(np.asarray(B.T @ error) / sigma**2)
    return G, g


def _tdoa_track_residuals(data, estimates: pd.DataFrame, p: dict) -> pd.DataFrame | None:
    """The run's range differences of the subset's pairs against the estimated track: per row t,
    anchor_id, ref_anchor_id, e = tdoa - (r_a - r_ref) and delta = r_a - r_ref (m, the track's
    distances, 3-D with the anchors' height offsets) and hx, hy, the pair's gradient u_a - u_ref
    (u: unit vector from the anchor to the track); None with too few rows."""
    members = data.members(p["anchors"])
    rows = data.usable_tdoa()
    rows = rows[rows["anchor_id"].isin(members) & rows["ref_anchor_id"].isin(members)]
    track = estimates.loc[np.isfinite(estimates["x"]) & np.isfinite(estimates["y"]), ["t", "x", "y"]]
    if len(rows) < MIN_INNOVATIONS or len(track) < 2:
        return None
    t = rows["t"].to_numpy(float)
    inside = (t >= track["t"].iloc[0]) & (t <= track["t"].iloc[-1])
    rows, t = rows[inside], t[inside]
    xy = np.column_stack([np.interp(t, track["t"], track[c]) for c in ("x", "y")])
    ids = sorted(set(rows["anchor_id"]) | set(rows["ref_anchor_id"]), key=str)
    slot = {a: k for k, a in enumerate(ids)}
    ends = np.column_stack([rows[side].map(slot).to_numpy(np.intp) for side in ("anchor_id", "ref_anchor_id")])
    pairs, pair = np.unique(ends, axis=0, return_inverse=True)
    model = TdoaModel(data.positions(ids), pairs, 1.0, data.height_offsets(ids))
    delta, gradient = model.pair_rows(xy, pair.ravel())
    out = pd.DataFrame({"t": t, "anchor_id": rows["anchor_id"].to_numpy(dtype=object),
                        "ref_anchor_id": rows["ref_anchor_id"].to_numpy(dtype=object),
                        "e": rows["tdoa_m"].to_numpy(float) - delta, "delta": delta,
                        "hx": gradient[:, 0], "hy": gradient[:, 1]})
    return out if len(out) >= MIN_INNOVATIONS else None


def tdoa_correction(data, estimates: pd.DataFrame, p: dict) -> dict | None:
    """Range scale s and per-anchor offsets b_a of r = s d + b_a seen through range differences,
    tdoa = s (d_a - d_ref) + b_a - b_ref, against the track of a first pass (no truth); None when
    the windows do not determine them.

    By projection through short windows (the form range_correction had before its smooth fit of the
    track's error, smooth_error_fit, which on range differences traded the scale against the
    offsets: a scale of 0.944 fitted on a simulated 10 Hz run without scale error, median 0.49 m
    against 0.20 m): over a window the track is close to the least-squares fix of the window's
    differences, so their residuals against it keep only
    (I - P_w) X_w theta, with X_w = [delta_w, D_w] (delta: the track's distance differences, for
    the scale error s - 1; D_w the pairs' incidence, +1 at the anchor, -1 at the reference) and
    P_w the projector onto the columns of the window's gradients u_a - u_ref. theta = (s - 1, b)
    is the least-squares solution of sum_w X_w' (I - P_w) X_w theta = sum_w X_w' (I - P_w) e_w over
    windows of WINDOW_S with >= 3 pairs whose gradients fix a position (smallest singular value
    >= MIN_SPREAD). A common offset cancels in differences: the most frequent reference is the
    gauge (b = 0, as metrics.ranging.fit_tdoa_bias). Residuals further than OUTLIER_SIGMAS
    normalised MADs from their pair's median (NLOS) are left out first. The scale is kept at 1
    where it and the offsets together are ill-conditioned (condition number of G scaled to a unit
    diagonal above MAX_CONDITION) or where it is within MIN_SCALE_ERROR of 1: the track's lag
    behind a moving target aliases into a scale of that size (0.996 fitted on a run without
    scale error, its offsets then off by ~2 cm; percent-level scale errors, e.g. a 7% one, are
    found to ~0.5%). two_pass fits twice (TDOA_FITS): on the plain track, then on the track
    corrected by the first fit, which a scale error had bent."""
    samples = _tdoa_track_residuals(data, estimates, p)
    if samples is None:
        return None
    error = samples["e"].to_numpy(float)
    centre = samples.groupby(["anchor_id", "ref_anchor_id"])["e"].transform("median").to_numpy()
    spread = robust_sigma(error - centre)
    samples = samples[np.abs(error - centre) <= OUTLIER_SIGMAS * max(spread, SIGMA_FLOOR_M)]
    refs = samples["ref_anchor_id"].value_counts()
    gauge = sorted(refs.index, key=lambda a: (-refs[a], str(a)))[0]
    anchors = sorted((set(samples["anchor_id"]) | set(samples["ref_anchor_id"])) - {gauge}, key=str)
    column = {a: k + 1 for k, a in enumerate(anchors)}
    window = np.floor((samples["t"].to_numpy(float) - samples["t"].min()) / WINDOW_S).astype(int)
    means = samples.assign(w=window).groupby(["w", "anchor_id", "ref_anchor_id"])[
        ["e", "delta", "hx", "hy"]].median().reset_index()
    n = 1 + len(anchors)
    G, g = np.zeros((n, n)), np.zeros(n)
    for _, rows in means.groupby("w"):
        if len(rows) < 3:
            continue
        H = rows[["hx", "hy"]].to_numpy()
        if np.linalg.svd(H, compute_uv=False)[-1] < MIN_SPREAD:
            continue
        X = np.zeros((len(rows), n))
        X[:, 0] = rows["delta"].to_numpy()
        for i, (a, b) in enumerate(zip(rows["anchor_id"], rows["ref_anchor_id"])):
            for anchor, sign in ((a, 1.0), (b, -1.0)):
                if anchor in column:                      # the gauge has no column (b = 0)
                    X[i, column[anchor]] += sign
        project = np.eye(len(rows)) - H @ np.linalg.pinv(H)
        G += X.T @ project @ X
        g += X.T @ project @ rows["e"].to_numpy()
    theta = _solve_scaled(G, g)
    held = theta is None or abs(theta[0]) < MIN_SCALE_ERROR          # the scale held at 1: not a fitted parameter
    if held:
        offsets = _solve_scaled(G[1:, 1:], g[1:])
        if offsets is None:
            return None
        theta = np.r_[0.0, offsets]
    return {"scale": 1.0 + float(theta[0]),
            "offsets_m": {str(gauge): 0.0, **{str(a): float(theta[k]) for a, k in column.items()}},
            "parameters": len(anchors) + (not held), "source": "self-fitted on the run's range differences (two-pass)"}


def _solve_scaled(G: np.ndarray, g: np.ndarray) -> np.ndarray | None:
    """G^-1 g, or None where G scaled to a unit diagonal (the unknowns' units apart) has a
    condition number above MAX_CONDITION or a zero diagonal (an unknown no window sees)."""
    diagonal = np.diag(G)
    if not len(g) or np.any(diagonal <= 0):
        return None
    w = 1.0 / np.sqrt(diagonal)
    scaled = G * w[:, None] * w[None, :]
    if np.linalg.cond(scaled) >= MAX_CONDITION:
        return None
    return w * np.linalg.solve(scaled, w * g)


def _anchors_in_tdoa(data, p) -> int:
    members = data.members(p["anchors"])
    rows = data.usable_tdoa()
    return len((set(rows["anchor_id"]) | set(rows["ref_anchor_id"])) & members)


def segment(data, p: dict, share: float):
    """The run cut to the central `share` of its usable measurements (ranges, RSS, TDOA) by time:
    the sub-run the noise candidates and the range correction are scored on (module docstring).
    Built once per run, range model and key (RunData.cached; the fit passes on it are cached on it)."""
    key = ("segment", share, p["preliminary_filter"], p["max_range_m"], range_calibration.model_key(data.range_model))
    return data.cached(key, lambda: _segment(data, p, share))


def _segment(data, p: dict, share: float):
    stamps = data.measurement_times(p["preliminary_filter"], p["max_range_m"])
    if share >= 1.0 or len(stamps) < 2:
        return data
    lo, hi = stamps[int((0.5 - share / 2) * (len(stamps) - 1))], stamps[int((0.5 + share / 2) * (len(stamps) - 1))]
    tables = {name: (frame[(frame["t"] >= lo) & (frame["t"] <= hi)] if name in MEASUREMENT_TABLES else frame)
              for name, frame in data.tables.items()}
    return replace(data, tables=tables, _cache={})


def _span(part) -> tuple[float, float]:
    """The first and last measurement time (s) of a sub-run."""
    t = np.concatenate([part.tables[name]["t"].to_numpy(float) for name in MEASUREMENT_TABLES if name in part.tables])
    return float(t.min()), float(t.max())


def _as_measured(score: tuple[float, float, int], model: dict, p: dict) -> float:
    """max_c L(c) of a pass on measurements corrected by a range model, z' = (z - b) / s (ranges and
    range differences alike), as the log-likelihood of the measurements as measured z: their density
    is that of z' divided by s, so the pass's n innovations pay n log s (without this a scale above 1
    would win by shrinking every residual). On `hybrid` the innovations mix ranges with RSS and the
    range count is not separated: the term is left out there."""
    ll, _, n = score
    return ll - n * np.log(model["scale"]) if p["measurements"] in ("toa", "tdoa") else ll


def refine(x: np.ndarray, ll: np.ndarray) -> float:
    """The maximum of the parabola through three points (x_i, ll_i) (x increasing) when the middle
    one is the best (a bracketed maximum), else the best point: an edge is not extrapolated."""
    best = int(np.argmax(ll))
    if best != 1 or not np.all(np.isfinite(ll)):
        return float(x[best])
    a, b, _ = np.polyfit(x, ll, 2)
    return float(np.clip(-b / (2 * a), x[0], x[-1])) if a < 0 else float(x[1])


def _score(run_pass, part, p: dict, span: float) -> tuple[float, float, int]:
    """(max_c L(c), c*, innovations used) of one pass with parameters p on the sub-run `part`;
    -inf with fewer than MIN_INNOVATIONS."""
    _, (y, S) = run_pass(part, p)
    ok = np.isfinite(y) & (S > 0)
    if ok.sum() < MIN_INNOVATIONS:
        return -np.inf, 1.0, int(ok.sum())
    return (*profile_likelihood(y[ok], S[ok], span), int(ok.sum()))


def _candidates(q: dict, noise: str) -> list[dict]:
    """The noise candidates (CANDIDATES) around the parameters q; `noise` the process-noise key."""
    return [dict(q, range_sigma_m=q["range_sigma_m"] * k_sigma, **{noise: q[noise] * k_accel})
            for k_sigma, k_accel in CANDIDATES]


def _rescore(run_pass, part, candidates: list[dict], best: int, known: tuple[float, float, int],
             span: float) -> list[tuple[float, float, int]]:
    """The candidates' scores on the segment `part`, the score of candidate `best` known. The
    likelihood is taken as unimodal in the ratio accel / sigma (the candidates' order): from an
    edge candidate, the middle one is scored and the far edge only where the middle one is higher
    (else it is set to -inf: below the middle one); from the middle one, both edges."""
    scores: list = [None, None, None]
    scores[best] = known
    order = [1] if best != 1 else [0, 2]
    for k in order:
        scores[k] = _score(run_pass, part, candidates[k], span)
    if best != 1:
        far = 2 - best
        scores[far] = _score(run_pass, part, candidates[far], span) if scores[1][0] > known[0] \
            else (-np.inf, 1.0, 0)
    return scores


def _without_range_model(part):
    """The segment `part` with the ranges as measured (built once per segment: RunData.cached). It
    shares the segment's cache: every cached value that reads the range model has it in its key
    (the measurement source its correction, the fit passes the model's key), so what does not
    depend on it (usable ranges, the epoch grid, the update mode) is built once."""
    return part.cached(("without range model",), lambda: replace(part, range_model=None, _cache=part._cache))


def _test_correction(run_pass, part, candidate: dict, corrected: tuple[float, float, int], model: dict, correct,
                     track: pd.DataFrame, p: dict, span: float) -> tuple[bool, tuple[float, float, int], dict]:
    """The likelihood-ratio tests of a range correction (module docstring, 4) with the best noise
    candidate, whose score on the segment `part` of the corrected run is `corrected`: (supported,
    the candidate's score on the segment with the ranges as measured, attrs)."""
    plain = _without_range_model(part)
    n = corrected[2]
    as_measured = _score(run_pass, plain, dict(candidate, range_calibration="none"), span)
    gain = _as_measured(corrected, model, p) - as_measured[0]
    penalty = 0.5 * model["parameters"] * np.log(n)
    attrs = {"self_fit_range_ll_gain": float(gain), "self_fit_range_ll_penalty": float(penalty)}
    supported = gain > penalty
    local = correct(track[track["t"].between(*_span(part))]) if supported else None
    if local is not None:                  # constant over the run? (module docstring, 4)
        local_score = _score(run_pass, replace(plain, range_model=local, _cache=plain._cache), candidate, span)
        local_gain = _as_measured(local_score, local, p) - _as_measured(corrected, model, p)
        local_penalty = 0.5 * local["parameters"] * np.log(n)
        attrs.update(self_fit_range_local_gain=float(local_gain), self_fit_range_local_penalty=float(local_penalty))
        supported = local_gain <= local_penalty
    attrs["self_fit_range_correction"] = "applied" if supported else "not supported"
    if supported:
        attrs["self_fit_range_scale"] = model["scale"]
    return supported, as_measured, attrs


def _scale_only(run_pass, plain, candidate: dict, model: dict, as_measured: tuple[float, float, int], p: dict,
                span: float) -> tuple[dict, tuple[float, float, int]] | None:
    """Where the local test rejected a range correction whose constant form passed the first test
    (module docstring, 4): the run's scale alone, r' = r / s without the offsets, kept when it
    raises max_c L(c) on the segment `plain` (ranges as measured) over the ranges as measured by
    more than the BIC penalty of its one parameter, 1/2 ln n. The local test speaks of the
    offsets (biases that change along the path); a scale is one number, estimated in the
    augmented pass apart from them, and a real range scale error (clock drift, a wrong speed of
    light in the firmware) is lost with them otherwise. (scale-only model, its score) or None.

    Not for the P model (`motion: p`, ekf_p): a random walk lags a moving target, and the lag
    enters the residuals of the scale and of the local fit alike (cucudasluv nlos/a-case-1: local
    gain 106 for ekf_p against 16 for tracker on the same ranges; there the scale alone made
    ekf_p's RMSE 0.968 m against 0.864 m as measured). Nor with the NLOS-aware noise
    (`range_sigma_per_wall_m` > 0), which models the excess of ranges through walls as noise: a
    scale read from those ranges is that excess's trend with distance (simulated Newcom++ variable
    runs: LOS ranges' slope against the true distance 0.999-1.001, all ranges' 1.018-1.050, the
    scale read 1.009-1.010; kept alone it raised that filter's RMSE on the 5 runs where it passed,
    e.g. 0.158 -> 0.196 m)."""
    if p["measurements"] not in ("toa", "hybrid") or model["scale"] == 1.0 or p.get("motion") == "p" \
            or p.get("range_sigma_per_wall_m", 0.0) > 0:
        return None
    scaled = dict(model, offsets_m={}, parameters=1, source=f"{model['source']}; scale only")
    score = _score(run_pass, replace(plain, range_model=scaled, _cache=plain._cache), candidate, span)
    gain = _as_measured(score, scaled, p) - as_measured[0]
    return (scaled, score) if gain > 0.5 * np.log(as_measured[2]) else None


def _judging(run_pass):
    """run_pass for the fit's passes, which judge the model: without gate_refix (filter_options),
    whose restart of a track that a misfit led astray would hide that misfit from the likelihood
    (a walk ranged one anchor at a time with 5% scale: the fit chose a 1.2 m range sigma with 28
    restarts, median 2.07 m against 0.34 m)."""
    return lambda data, p: run_pass(data, dict(p, gate_refix=False))


def two_pass(data, p: dict, run_pass, output) -> pd.DataFrame:
    """The self-fitted estimates of one run (module docstring); run_pass(data, p) -> (estimates,
    (y, S)) runs one fitting pass (an EKF filter pass) and returns its innovations; output(data, p)
    -> estimates is the estimator's own single pass (filter or smoother), run once with the fit."""
    span = 2.0 * p["max_range_m"]
    q = dict(p, self_fit="none")
    run_pass = _judging(run_pass)
    run, model, fitted, correct, track = data, None, {}, None, None
    if p["measurements"] in ("toa", "hybrid") and p["range_calibration"] == "none" \
            and p["range_self_calibration"] == "none" and _anchors_ranged(data, p) >= MIN_ANCHORS_FOR_OFFSETS:
        track, _ = run_pass(data, dict(q, range_self_calibration="scale"))
        scale = float(track.attrs.get("range_scale", 1.0))
        correct = lambda track: range_correction(data, track, p, scale)    # noqa: E731
        model = correct(track)
    elif p["measurements"] == "tdoa" and p["range_calibration"] == "none" \
            and _anchors_in_tdoa(data, p) >= MIN_ANCHORS_FOR_OFFSETS:
        track, _ = run_pass(data, q)
        correct = lambda track: tdoa_correction(data, track, p)            # noqa: E731
        for refit in range(TDOA_FITS):
            model = correct(track)
            if model is None or refit == TDOA_FITS - 1:
                break
            track, _ = run_pass(replace(data, range_model=model, _cache=data._cache),
                                dict(q, range_calibration="other_run"))
    if model is not None:
        run = replace(data, range_model=model, _cache=data._cache)
        q = dict(q, range_calibration="other_run")
    part = segment(run, q, SEARCH_SHARE)
    noise = PROCESS_NOISE[q.get("motion") == "p"]
    candidates = _candidates(q, noise)
    scores = [_score(run_pass, part, candidate, span) for candidate in candidates]
    ll = np.array([score[0] for score in scores])
    if not np.isfinite(ll).any():          # too few innovations on the segment: the configured noise
        out = output(run, q)
        if model is not None:
            out.attrs.update(self_fit_range_correction="applied untested (too few measurements)",
                             self_fit_range_scale=model["scale"])
        return out
    if model is not None:                  # likelihood-ratio tests of the range correction (module docstring, 4)
        best = int(np.argmax(ll))
        supported, as_measured, tests = _test_correction(run_pass, part, candidates[best], scores[best], model,
                                                         correct, track, p, span)
        fitted.update(tests)
        scaled = _scale_only(run_pass, _without_range_model(part), candidates[best], model, as_measured, p, span) \
            if not supported and "self_fit_range_local_gain" in tests else None
        if scaled is not None:             # the scale alone; the noise chosen again with it
            model, known = scaled
            run = replace(data, range_model=model, _cache=data._cache)
            part = replace(_without_range_model(part), range_model=model, _cache=part._cache)
            scores = _rescore(run_pass, part, candidates, best, known, span)
            ll = np.array([score[0] for score in scores])
            fitted.update(self_fit_range_correction="applied, scale only (offsets not constant)",
                          self_fit_range_scale=model["scale"])
        elif not supported:                # the noise is chosen again on the ranges as measured
            run, q, part = data, dict(q, range_calibration="none"), _without_range_model(part)
            candidates = _candidates(q, noise)
            scores = _rescore(run_pass, part, candidates, best, as_measured, span)
            ll = np.array([score[0] for score in scores])
            if not np.isfinite(ll).any():  # too few innovations as measured: the configured noise
                out = output(run, q)
                out.attrs.update(fitted)
                return out
    x = np.log([k_accel / k_sigma for k_sigma, k_accel in CANDIDATES])
    used = np.log([[c["range_sigma_m"], c[noise]] for c in candidates])
    fit = used + 0.5 * np.log([[score[1]] for score in scores])
    chosen = refine(x, ll)
    sigma, accel = (float(np.exp(np.interp(chosen, x, used[:, k]))) for k in range(2))
    out = output(run, dict(q, range_sigma_m=sigma, **{noise: accel}))
    ran, fitted_key = FITTED_NOISE_KEYS[noise]
    fitted.update({"self_fit_ratio_factor": float(np.exp(chosen)), "self_fit_run_sigma_m": sigma, ran: accel,
                   "self_fit_range_sigma_m": max(float(np.exp(np.interp(chosen, x, fit[:, 0]))), SIGMA_FLOOR_M),
                   fitted_key: float(np.exp(np.interp(chosen, x, fit[:, 1])))})
    out.attrs.update(fitted)
    return out
