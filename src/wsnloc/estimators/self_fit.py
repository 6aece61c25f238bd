"""Two-pass self-fit (offline, no truth): the noise and the range errors of the run at hand.

Real data break a filter's assumptions in a few common ways: the range noise is not the
configured one, the motion is livelier or calmer than the process noise says, the ranges carry
a common scale error and per-anchor offsets. `self_fit: two_pass` (the `tracker` default) learns
them from the run itself, in three passes of the same filter:

1. **Range scale and per-anchor offsets** (ranges, >= 4 anchors ranged, no configured or donor
   calibration, which wins): a first pass with the state augmented by a common range scale
   (estimators.self_calibration; observable while the target moves among >= 4 anchors); then
   the per-anchor offsets against that pass's track (range_correction: least squares through
   each window's geometry, undoing what the track absorbed). The ranges are corrected
   (estimators.range_calibration) for the next passes.
2. **Noise, by maximum likelihood of the innovations.** Two passes with the configured
   (range_sigma_m, accel_sigma_mps2 or p_sigma_m) and with a livelier candidate (sigma / 2, process noise x 3: a
   six times larger process-to-measurement noise ratio, i.e. a higher gain). Each pass records
   every innovation y_i = z_i - h_i(x-) and its variance S_i = (H P- H' + R)_ii, gated ones
   included. Scaling Q and R together by c leaves a linear filter's track unchanged and scales
   every S_i by c, so per candidate the likelihood is profiled over c:
       L(c) = sum_i log[(1 - eps) N(y_i; 0, c S_i) + eps / span],
   a Gaussian with a uniform outlier component (eps = OUTLIER_SHARE over span = 2 max_range_m:
   reflections and NLOS ranges do not decide the noise), c on a log grid (CLAMP).
3. The pass with the larger max_c L(c) is the output; attrs `self_fit_*` give the candidate and
   the fitted noise, range_sigma_m sqrt(c*) (floored at SIGMA_FLOOR_M) and accel sqrt(c*), and
   the range scale. Because the likelihood is that of the innovations, which carry the state's
   own uncertainty H P H', the fitted sigma does not collapse onto the track the way residuals
   against the filter's own output do.

Cost: three passes of the filter plus the fits (milliseconds); about 3x one plain pass.
Online (live) use has no second pass: `range_self_calibration` (state augmentation) and the
gate's widening (filter_options) adapt as the data come.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

MODES = ("none", "two_pass")
LIVELIER = (0.5, 3.0)                  # candidate: sigma x 0.5, process noise x 3 (ratio q / r x 36 in variance)
PROCESS_NOISE = ("accel_sigma_mps2", "p_sigma_m")   # the PV / PVA and the P (random walk) model's
OUTLIER_SHARE = 0.05                   # eps of the uniform outlier component
CLAMP = (0.05, 20.0)                   # c* searched on a log grid in this range
GRID = np.exp(np.linspace(np.log(CLAMP[0]), np.log(CLAMP[1]), 121))
SIGMA_FLOOR_M = 0.01
MIN_INNOVATIONS = 50
MIN_ANCHORS_FOR_OFFSETS = 4
WINDOW_S = 1.0                         # windows of the offsets' projection fit
MIN_SPREAD = 0.5                       # smallest singular value of a window's unit-vector matrix H
MAX_CONDITION = 1e3
OUTLIER_SIGMAS = 4.0


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

    A track computed from biased ranges has moved to absorb part of the biases: over a short
    window it is close to the least-squares fix of the window's ranges, whose residuals keep only
    e = (I - P_H) b, P_H = H (H'H)^-1 H' the projector onto the columns of the window's Jacobian
    H (rows: unit vectors from the track to the anchors ranged), i.e. about 1 - 2/m of a bias
    with m anchors. So the offsets are the least-squares solution of
        sum_w M_w' (I - P_w) M_w b = sum_w M_w' (I - P_w) e_w
    over windows w of WINDOW_S with >= 3 anchors ranged in directions spread enough to fix a
    position (the smallest singular value of H at least MIN_SPREAD; M_w selects them, e_w their
    median residuals r - s d); the median residual per anchor where that system is singular or
    ill-conditioned (condition number above MAX_CONDITION). Residuals further than OUTLIER_SIGMAS
    normalised MADs from their anchor's median (reflections, NLOS) are left out first."""
    from wsnloc.diagnosis import track_distances

    samples = track_distances(data, estimates, p)
    if samples is None:
        return None
    ids = samples["anchor_id"].astype(str).to_numpy()
    error = samples["range_m"].to_numpy(float) - scale * samples["true_distance_m"].to_numpy(float)
    anchors, column = np.unique(ids, return_inverse=True)
    centre = pd.Series(error).groupby(column).transform("median").to_numpy()
    spread = 1.4826 * np.median(np.abs(error - centre))
    inlier = np.abs(error - centre) <= OUTLIER_SIGMAS * max(spread, SIGMA_FLOOR_M)
    samples, error, column = samples[inlier], error[inlier], column[inlier]
    xy = data.positions(anchors)
    diff = samples[["true_x", "true_y"]].to_numpy(float) - xy[column]
    unit = diff / np.maximum(samples["true_distance_m"].to_numpy(float), 1e-3)[:, None]
    window = np.floor((samples["t"].to_numpy(float) - samples["t"].min()) / WINDOW_S).astype(int)
    frame = pd.DataFrame({"w": window, "a": column, "e": error, "ux": unit[:, 0], "uy": unit[:, 1]})
    means = frame.groupby(["w", "a"]).median().reset_index()
    m = len(anchors)
    G, g = np.zeros((m, m)), np.zeros(m)
    for _, rows in means.groupby("w"):
        if len(rows) < 3:
            continue
        a, H = rows["a"].to_numpy(), rows[["ux", "uy"]].to_numpy()
        if np.linalg.svd(H, compute_uv=False)[-1] < MIN_SPREAD:
            continue                    # anchors seen in nearly one direction: a shift along it is a bias
        project = np.eye(len(a)) - H @ np.linalg.pinv(H)
        G[np.ix_(a, a)] += project
        g[a] += project @ rows["e"].to_numpy()
    medians = pd.Series(error).groupby(column).median().to_numpy()
    if np.linalg.cond(G) < MAX_CONDITION:
        offsets = np.linalg.solve(G, g)
    else:
        offsets = medians
    return {"scale": scale, "offsets_m": {str(a): float(b) for a, b in zip(anchors, offsets)},
            "source": "self-fitted on the run (two-pass)"}


def two_pass(data, p: dict, run_pass) -> pd.DataFrame:
    """The self-fitted estimates of one run (module docstring); run_pass(data, p) -> (estimates,
    (y, S)) runs one pass of the filter and returns its innovations."""
    span = 2.0 * p["max_range_m"]
    q = dict(p, self_fit="none")
    run, fitted = data, {}
    if p["measurements"] in ("toa", "hybrid") and p["range_calibration"] == "none" \
            and p["range_self_calibration"] == "none" and _anchors_ranged(data, p) >= MIN_ANCHORS_FOR_OFFSETS:
        scaled, _ = run_pass(data, dict(q, range_self_calibration="scale"))
        model = range_correction(data, scaled, p, float(scaled.attrs.get("range_scale", 1.0)))
        if model is not None:
            run = replace(data, range_model=model, _cache=data._cache)
            q = dict(q, range_calibration="other_run")
            fitted["self_fit_range_scale"] = model["scale"]
    first, innovations = run_pass(run, q)
    livelier = dict(q, range_sigma_m=q["range_sigma_m"] * LIVELIER[0],
                    **{k: q[k] * LIVELIER[1] for k in PROCESS_NOISE if k in q})
    scored = []
    for candidate, (estimates, (y, S)) in ((q, (first, innovations)), (livelier, run_pass(run, livelier))):
        ok = np.isfinite(y) & (S > 0)
        ll, c = profile_likelihood(y[ok], S[ok], span) if ok.sum() >= MIN_INNOVATIONS else (-np.inf, 1.0)
        scored.append((ll, c, candidate, estimates))
    ll, c, best, out = max(scored, key=lambda s: s[0])
    if np.isfinite(ll):
        fitted.update(self_fit_candidate="livelier" if best is livelier else "configured",
                      self_fit_range_sigma_m=max(best["range_sigma_m"] * np.sqrt(c), SIGMA_FLOOR_M),
                      self_fit_accel_sigma_mps2=best["accel_sigma_mps2"] * np.sqrt(c),
                      **({"self_fit_p_sigma_m": best["p_sigma_m"] * np.sqrt(c)} if p.get("motion") == "p" else {}))
    out.attrs.update(fitted)
    return out
