"""Measurement quality against ground truth: range errors and the path-loss fit.

Uses only processed tables (ranges, rss, truth, anchors) and the campaign geometry
(walls), never simulator internals, so it applies equally to real logs.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.metrics.stats import robust_sigma


def truth_at(truth: pd.DataFrame, t: np.ndarray) -> np.ndarray:
    """(N, 2) true position at times t (s) by linear interpolation; NaN outside the truth span
    (everywhere without truth: a run's truth is optional)."""
    if len(truth) == 0:
        return np.full((len(t), 2), np.nan)
    x = np.interp(t, truth["t"], truth["x"], left=np.nan, right=np.nan)
    y = np.interp(t, truth["t"], truth["y"], left=np.nan, right=np.nan)
    return np.column_stack([x, y])


def positions_and_distances(t: np.ndarray, anchor_of_rows: pd.Series, truth: pd.DataFrame, campaign: Campaign,
                            anchors: pd.DataFrame | None = None) -> tuple[np.ndarray, ...]:
    """(inside, position, slot, distance) of measurements at times t (s) to the anchors
    `anchor_of_rows`: the indices of the rows inside the truth span, the true position there
    ((n, 2), m), each row's slot in the anchor table and the true distance (m).

    The distance is 3-D, sqrt(dx^2 + dy^2 + (z_anchor - h_tag)^2), when the anchor has a
    height and the tag's is known: the truth's z at t (a 3-D truth), else the campaign's fixed
    tag height; otherwise 2-D.
    """
    position = truth_at(truth, t)
    inside = np.flatnonzero(np.isfinite(position[:, 0]))
    t, position = t[inside], position[inside]
    anchors = campaign.anchors if anchors is None else anchors
    slot = anchor_slots(anchor_of_rows.iloc[inside], anchors["anchor_id"])
    if (slot < 0).any():
        raise KeyError(f"anchors not in the anchor table: {sorted(set(anchor_of_rows.iloc[inside][slot < 0]))}")
    anchor_xy = anchors[["x", "y"]].to_numpy(dtype=float)
    if "z" in truth and np.isfinite(truth["z"].to_numpy(float)).any():      # the tag's height at each time
        z = anchors["z"].to_numpy(dtype=float)[slot] if "z" in anchors else np.full(len(slot), np.nan)
        given = np.isfinite(truth["z"].to_numpy(float))
        tag_z = np.interp(t, truth["t"][given], truth["z"][given])
        dz = np.where(np.isfinite(z), z - tag_z, 0.0)
    else:
        dz = _height_difference(anchors, campaign.tag_height_m)[slot]
    distance = np.sqrt((position[:, 0] - anchor_xy[slot, 0]) ** 2 + (position[:, 1] - anchor_xy[slot, 1]) ** 2
                       + dz ** 2)
    return inside, position, slot, distance


def _with_geometry(frame: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign,
                   anchors: pd.DataFrame | None = None) -> pd.DataFrame:
    """The rows of frame inside the truth span with the true position (true_x, true_y, m), the
    true distance (m, positions_and_distances) and the walls crossed between the true position
    and the anchor (los: none)."""
    inside, position, slot, distance = positions_and_distances(frame["t"].to_numpy(), frame["anchor_id"], truth,
                                                               campaign, anchors)
    frame = frame.take(inside)
    anchors = campaign.anchors if anchors is None else anchors
    new = {"true_x": position[:, 0], "true_y": position[:, 1], "true_distance_m": distance,
           "walls": _walls_per_anchor(position, slot, anchors[["x", "y"]].to_numpy(dtype=float), campaign)}
    new["los"] = new["walls"] == 0
    return pd.concat([frame, pd.DataFrame(new, index=frame.index)], axis=1)


def anchor_slots(anchor_of_rows: pd.Series, anchor_ids) -> np.ndarray:
    """Position in anchor_ids of each row's anchor, -1 when not listed (or missing): the rows'
    few distinct ids are looked up once (factorize), not every row."""
    codes, uniques = pd.factorize(anchor_of_rows)
    slot_of = {anchor: k for k, anchor in enumerate(anchor_ids)}
    return np.array([slot_of.get(anchor, -1) for anchor in uniques] + [-1])[codes]


def _height_difference(anchors: pd.DataFrame, tag_height: float | None) -> np.ndarray:
    """Per anchor, z_anchor - h_tag (m); 0 when the anchor has no height or the tag none (2-D)."""
    z = anchors["z"].to_numpy(dtype=float) if "z" in anchors else np.full(len(anchors), np.nan)
    return np.where(np.isfinite(z), z - tag_height, 0.0) if tag_height is not None else np.zeros(len(anchors))


def _walls_per_anchor(position: np.ndarray, slot: np.ndarray, anchor_xy: np.ndarray, campaign: Campaign) -> np.ndarray:
    """Walls crossed by the link from each position (N, 2, m) to its anchor (row slot of
    anchor_xy), counted one anchor at a time (its rows' (n, walls) arrays stay small)."""
    walls = np.full(len(slot), -1)
    order = np.argsort(slot, kind="stable")
    starts = np.flatnonzero(np.diff(slot[order], prepend=-1))
    for rows in np.split(order, starts[1:]):
        if len(rows):
            walls[rows] = campaign.walls_between(position[rows], anchor_xy[slot[rows[0]]])
    return walls


def range_errors(ranges: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign,
                 anchors: pd.DataFrame | None = None) -> pd.DataFrame:
    """Valid ranges (status 0) with error = measured - true distance (m) and a LOS flag."""
    valid = ranges[ranges["status"] == 0]
    frame = _with_geometry(valid, truth, campaign, anchors)
    frame["error_m"] = frame["range_m"] - frame["true_distance_m"]
    return frame


def rss_with_distance(rss: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign,
                      anchors: pd.DataFrame | None = None) -> pd.DataFrame:
    """RSS samples with the true distance (m) and walls crossed."""
    return _with_geometry(rss, truth, campaign, anchors)


def tdoa_with_distances(tdoa: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign,
                        anchors: pd.DataFrame | None = None) -> pd.DataFrame:
    """TDOA rows (range difference tdoa_m between anchor_id and ref_anchor_id) inside the truth
    span with the true (3-D) distance from the true position to each anchor of the pair:
    true_distance_m (anchor_id) and true_ref_distance_m (ref_anchor_id), in m."""
    rows = tdoa.reset_index(drop=True)
    to_anchor = _with_geometry(rows[["t", "anchor_id"]], truth, campaign, anchors)
    to_ref = _with_geometry(rows[["t"]].assign(anchor_id=rows["ref_anchor_id"]), truth, campaign, anchors)
    return rows.loc[to_anchor.index].assign(true_distance_m=to_anchor["true_distance_m"],
                                            true_ref_distance_m=to_ref["true_distance_m"])


def fit_path_loss(rss_dbm, distance_m, d0_m: float = 1.0) -> dict[str, float]:
    """Least-squares fit of P = P0 - 10 n log10(d / d0) + e; sigma = std of the residual e (dB).

    Samples closer than d0 are left out (the model is not defined below d0).
    """
    p = np.asarray(rss_dbm, dtype=float)
    d = np.asarray(distance_m, dtype=float)
    keep = np.isfinite(p) & np.isfinite(d) & (d >= d0_m)
    if keep.sum() < 3:
        return {"P0_dBm": float("nan"), "n": float("nan"), "sigma_dB": float("nan"), "samples": int(keep.sum())}
    design = np.column_stack([np.ones(keep.sum()), -10.0 * np.log10(d[keep] / d0_m)])
    (p0, n), *_ = np.linalg.lstsq(design, p[keep], rcond=None)
    residual = p[keep] - design @ np.array([p0, n])
    return {"P0_dBm": float(p0), "n": float(n), "sigma_dB": float(residual.std(ddof=2)),
            "samples": int(keep.sum())}


def fit_path_loss_per_anchor(rss_dbm, distance_m, anchor_id, d0_m: float = 1.0,
                             exponent: float | None = None) -> dict:
    """Least-squares fit of P_i = P0 + o_a(i) - 10 n log10(d_i / d0) + e_i with one P0 per
    receiver a (hardware gains differ by several dB): P0 the mean of the receivers' P0s, o_a
    their offsets from it (dB, summing to 0), n common (fitted, or the given `exponent`) and
    sigma the std of e (dB). With offsets free, n comes from the distance changes seen by each
    receiver, not from which receivers happen to be far (a fit with one P0 confounds the two).
    Samples closer than d0 are left out. Returns {P0_dBm, n, sigma_dB, offsets_dB: {a: o_a}, samples}.
    """
    p = np.asarray(rss_dbm, dtype=float)
    d = np.asarray(distance_m, dtype=float)
    ids = np.asarray(anchor_id, dtype=object)
    keep = np.isfinite(p) & np.isfinite(d) & (d >= d0_m)
    p, ids, loss = p[keep], ids[keep], -10.0 * np.log10(d[keep] / d0_m)
    receivers, column = np.unique(ids, return_inverse=True) if len(ids) else (np.array([]), np.array([], int))
    if len(p) < len(receivers) + 2:
        return {"P0_dBm": float("nan"), "n": float("nan"), "sigma_dB": float("nan"), "offsets_dB": {},
                "samples": int(len(p))}
    if exponent is None:
        n, p0s = _weighted_line(p, loss, column, np.ones(len(p)))
    else:
        n = float(exponent)
        p0s = np.bincount(column, p - n * loss) / np.bincount(column)
    residual = p - n * loss - p0s[column]
    p0 = float(p0s.mean())
    return {"P0_dBm": p0, "n": float(n), "sigma_dB": float(residual.std(ddof=len(receivers) + (exponent is None))),
            "offsets_dB": {str(a): float(b - p0) for a, b in zip(receivers, p0s)}, "samples": int(len(p))}


RANGE_FIT_TOLERANCE_M = 1e-11     # IRLS stops when no fitted range moves by more than this (m)
RANGE_FIT_ROUNDING = 1e-12        # ... or at the rounding floor: steps below this share of the largest
                                  # range that no longer shrink (long ranges, many samples)
RANGE_FIT_MAX_ITERATIONS = 1000


def fit_range_bias(range_m, true_distance_m, anchor_id) -> dict:
    """Robust fit of r = s d + b_a + e: a common scale s and one offset b_a (m) per anchor.

    Minimises the soft-L1 (pseudo-Huber) cost sum_i f^2 (sqrt(1 + (e_i / f)^2) - 1) of the
    residuals e_i = r_i - s d_i - b_a(i), its scale f the normalised MAD of the ordinary
    least-squares residual (at least 1 mm), so that reflections and NLOS ranges (a few, large,
    one-sided) do not pull the fit; sigma_m is the normalised MAD of the robust residual.
    Needs two distinct distances for at least one anchor.

    The cost is convex and its minimiser solves sum_i w_i e_i (d_i, 1_a(i)) = 0 with
    w_i = 1 / sqrt(1 + (e_i / f)^2): iteratively reweighted least squares (_weighted_line
    with the weights of the previous fit, from the ordinary fit w = 1) lowers the cost at
    every step and stops when no fitted range s d_i + b_a(i) moves by more than
    RANGE_FIT_TOLERANCE_M, or when steps below RANGE_FIT_ROUNDING max|r| stop shrinking
    (round-off of the weighted sums, not the fit, is then moving it); the minimiser is scipy.optimize.least_squares(loss="soft_l1")'s.
    """
    r = np.asarray(range_m, dtype=float)
    d = np.asarray(true_distance_m, dtype=float)
    ids = np.asarray(anchor_id, dtype=object)
    keep = np.isfinite(r) & np.isfinite(d)
    r, d, ids = r[keep], d[keep], ids[keep]
    anchors, column = np.unique(ids, return_inverse=True)
    if len(r) < len(anchors) + 2:
        raise ValueError(f"range calibration needs more samples than unknowns ({len(r)} for {len(anchors) + 1})")
    scale, offsets = _weighted_line(r, d, column, np.ones(len(r)))
    f_scale = max(robust_sigma(r - scale * d - offsets[column]), 1e-3)
    floor, last_moved = RANGE_FIT_ROUNDING * np.max(np.abs(r)), np.inf
    for _ in range(RANGE_FIT_MAX_ITERATIONS):
        residual = r - scale * d - offsets[column]
        new_scale, new_offsets = _weighted_line(r, d, column, 1.0 / np.sqrt(1.0 + (residual / f_scale) ** 2))
        moved = np.max(np.abs((new_scale - scale) * d + (new_offsets - offsets)[column]))
        scale, offsets = new_scale, new_offsets
        if moved <= RANGE_FIT_TOLERANCE_M or (moved <= floor and moved >= last_moved):
            break
        last_moved = moved
    else:
        raise ValueError(f"range calibration: no convergence in {RANGE_FIT_MAX_ITERATIONS} iterations")
    residual = r - scale * d - offsets[column]
    return {"scale": float(scale), "offsets_m": {str(a): float(b) for a, b in zip(anchors, offsets)},
            "sigma_m": robust_sigma(residual - np.median(residual)), "samples": int(len(r))}


def fit_tdoa_bias(tdoa_m, true_anchor_m, true_ref_m, anchor_id, ref_id) -> dict:
    """Robust fit of the range calibration r = s d + b_a seen through range differences:
    tdoa_i = s (d_a(i) - d_ref(i)) + b_a(i) - b_ref(i) + e_i, a common scale s and one offset
    b_a (m) per anchor. Only offset differences are observable: the most frequent reference
    is the gauge (b = 0) and the others are relative to it (a common offset cancels when the
    calibration is applied). Linear in (s, b): the soft-L1 cost of fit_range_bias (its scale f
    the normalised MAD of the ordinary least-squares residual, at least 1 mm) minimised by
    scipy.optimize.least_squares from the ordinary fit; sigma_m is the normalised MAD of the
    robust residual (the noise of a difference)."""
    from scipy.optimize import least_squares

    z = np.asarray(tdoa_m, dtype=float)
    delta = np.asarray(true_anchor_m, dtype=float) - np.asarray(true_ref_m, dtype=float)
    a, b = np.asarray(anchor_id, dtype=object), np.asarray(ref_id, dtype=object)
    keep = np.isfinite(z) & np.isfinite(delta)
    z, delta, a, b = z[keep], delta[keep], a[keep], b[keep]
    if not len(z):
        raise ValueError("TDOA calibration needs range differences with truth")
    refs, counts = np.unique(b, return_counts=True)
    gauge = refs[np.argmax(counts)]
    anchors = sorted((set(a) | set(b)) - {gauge})
    design = np.zeros((len(z), 1 + len(anchors)))
    design[:, 0] = delta
    column = {anchor: k + 1 for k, anchor in enumerate(anchors)}
    for ids, sign in ((a, 1.0), (b, -1.0)):
        for anchor, k in column.items():
            design[ids == anchor, k] += sign
    if len(z) < design.shape[1] + 2 or np.linalg.matrix_rank(design) < design.shape[1]:
        raise ValueError(f"TDOA calibration: {len(z)} differences do not determine the scale and "
                         f"{len(anchors)} offsets (distinct distance differences needed)")
    start = np.linalg.lstsq(design, z, rcond=None)[0]
    f_scale = max(robust_sigma(z - design @ start), 1e-3)
    theta = least_squares(lambda th: design @ th - z, start, loss="soft_l1", f_scale=f_scale).x
    residual = z - design @ theta
    offsets = {str(gauge): 0.0, **{str(anchor): float(theta[k]) for anchor, k in column.items()}}
    return {"scale": float(theta[0]), "offsets_m": offsets,
            "sigma_m": robust_sigma(residual - np.median(residual)), "samples": int(len(z))}


def _weighted_line(r: np.ndarray, d: np.ndarray, column: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted least squares of r = s d + b_a (a = column, weights w): the scale from the
    per-anchor centred samples, s = sum w (d - dbar_a)(r - rbar_a) / sum w (d - dbar_a)^2, and
    b_a = rbar_a - s dbar_a, with dbar_a, rbar_a the weighted means of anchor a's samples."""
    total = np.bincount(column, w)
    d_mean = np.bincount(column, w * d) / total
    r_mean = np.bincount(column, w * r) / total
    dc = d - d_mean[column]
    spread = np.sum(w * dc * dc)
    if not spread > 0:
        raise ValueError("range calibration needs two distinct distances to one anchor")
    scale = np.sum(w * dc * (r - r_mean[column])) / spread
    return scale, r_mean - scale * d_mean
