"""Batched Min-Max and multilateration (geometry.lateration) and batched epoch fixes
(estimators.fixes) against the per-epoch forms and the per-epoch reference algorithm, on
random geometries with degenerate epochs (collinear or coincident anchors, 2 anchors,
NaN / negative / infinite ranges, NaN anchors, a tag on an anchor)."""

import numpy as np
import pytest
from synthetic import RSS_MODEL, one_at_a_time, run_data, tables_for, walk

from wsnloc.estimators import registry
from wsnloc.estimators.measurements import MeasurementSource, RssParams
from wsnloc.geometry import lateration
from wsnloc.geometry.lateration import (
    min_max,
    min_max_batch,
    multilateration,
    multilateration_batch,
)
from wsnloc.geometry.selection import smallest_per_epoch
from synthetic import k_smallest


# ---- the per-epoch algorithm before vectorisation (the oracle) ------------------------------
def _reference_usable(anchors, ranges):
    anchors, ranges = np.asarray(anchors, float).reshape(-1, 2), np.asarray(ranges, float).reshape(-1)
    keep = np.isfinite(ranges) & (ranges >= 0) & np.all(np.isfinite(anchors), axis=1)
    return anchors[keep], ranges[keep]


def _reference_min_max(anchors, ranges):
    a, d = _reference_usable(anchors, ranges)
    if len(d) < 3:
        return None
    return (np.max(a - d[:, None], axis=0) + np.min(a + d[:, None], axis=0)) / 2.0


def _reference_linear(a, d):
    matrix = 2.0 * (a[-1][None, :] - a[:-1])
    rhs = d[:-1] ** 2 - d[-1] ** 2 - np.sum(a[:-1] ** 2, axis=1) + np.sum(a[-1] ** 2)
    if np.linalg.cond(matrix) > 1e8:
        return None
    return np.linalg.lstsq(matrix, rhs, rcond=None)[0]


def _reference_gauss_newton(a, d, p):
    diff = p - a
    dist = np.hypot(diff[:, 0], diff[:, 1])
    current = float(np.sum((dist - d) ** 2))
    for _ in range(10):
        safe = np.maximum(dist, 1e-9)
        jac = diff / safe[:, None]
        (jxx, jxy), (_, jyy) = jac.T @ jac
        gx, gy = jac.T @ (safe - d)
        det = jxx * jyy - jxy * jxy
        if not (np.isfinite(det) and det != 0.0):
            break
        step = np.array([(jyy * gx - jxy * gy) / det, (jxx * gy - jxy * gx) / det])
        candidate = p - step
        candidate_diff = candidate - a
        candidate_dist = np.hypot(candidate_diff[:, 0], candidate_diff[:, 1])
        new = float(np.sum((candidate_dist - d) ** 2))
        if not new < current:
            break
        p, current, diff, dist = candidate, new, candidate_diff, candidate_dist
        if np.hypot(step[0], step[1]) < 1e-9:
            break
    return p


def _reference_multilateration(anchors, ranges, refine=True):
    a, d = _reference_usable(anchors, ranges)
    if len(d) < 3:
        return None
    p = _reference_linear(a, d)
    return p if p is None or not refine else _reference_gauss_newton(a, d, p)


# ---- random epochs -------------------------------------------------------------------------
def random_epochs(seed: int, epochs: int = 400, width: int = 8):
    """(anchors (epochs, width, 2), ranges (epochs, width)) [m]: noisy ranges to 3..width anchors
    in a 30 m x 20 m area, NaN-padded, and every fifth epoch made degenerate."""
    rng = np.random.default_rng(seed)
    anchors = rng.uniform([0, 0], [30, 20], (epochs, width, 2))
    tags = rng.uniform([0, 0], [30, 20], (epochs, 2))
    ranges = np.hypot(*np.moveaxis(anchors - tags[:, None], -1, 0)) + rng.normal(0, 0.5, (epochs, width))
    counts = rng.integers(3, width + 1, epochs)
    ranges[np.arange(width)[None, :] >= counts[:, None]] = np.nan           # padding
    for e in range(0, epochs, 5):
        kind = (e // 5) % 9
        if kind == 0:                                                       # collinear, general line
            anchors[e, :, 0] = np.linspace(0, 30, width)
            anchors[e, :, 1] = 2.0 + 0.5 * anchors[e, :, 0]
        elif kind == 1:                                                     # collinear, horizontal
            anchors[e, :, 1] = 7.0
        elif kind == 2:                                                     # 2 usable ranges
            ranges[e, 2:] = np.nan
        elif kind == 3:                                                     # NaN / inf / negative in the middle
            ranges[e, [0, 2]] = [np.nan, -1.0]
            ranges[e, 1] = np.inf
        elif kind == 4:                                                     # NaN anchor coordinate
            anchors[e, 1, 0] = np.nan
        elif kind == 5:                                                     # coincident anchors
            anchors[e, :] = anchors[e, 0]
        elif kind == 6:                                                     # tag exactly on an anchor
            ranges[e, :counts[e]] = np.hypot(*(anchors[e, :counts[e]] - anchors[e, 0]).T)
        elif kind == 7:                                                     # nearly collinear
            anchors[e, :, 1] = 5.0 + 1e-7 * rng.normal(size=width)
        else:                                                               # no usable range at all
            ranges[e] = np.nan
    return anchors, ranges


def _as_fixes(solutions):
    return np.array([np.full(2, np.nan) if s is None else s for s in solutions], dtype=float)


def _reference(solver, anchors, ranges, **options):
    return _as_fixes([solver(a, d, **options) for a, d in zip(anchors, ranges)])


SEEDS = [0, 1, 2]                # relative 1e-12: nearly collinear anchors put fixes ~1e8 m away


@pytest.mark.parametrize("seed", SEEDS)
def test_min_max_batch_equals_the_reference_per_epoch(seed):
    anchors, ranges = random_epochs(seed)
    batch = min_max_batch(anchors, ranges)
    np.testing.assert_allclose(batch, _reference(_reference_min_max, anchors, ranges), rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(batch, _reference(min_max, anchors, ranges))
    assert np.isnan(batch[:, 0]).sum() > 0 and np.isfinite(batch[:, 0]).sum() > len(batch) / 2


@pytest.mark.parametrize("seed", SEEDS)
def test_batched_linear_solution_equals_the_reference_per_epoch(seed):
    anchors, ranges = random_epochs(seed)
    batch = multilateration_batch(anchors, ranges, refine=False)
    np.testing.assert_allclose(batch, _reference(_reference_multilateration, anchors, ranges, refine=False),
                               rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(batch, _reference(multilateration, anchors, ranges, refine=False))


@pytest.mark.parametrize("seed", SEEDS)
def test_batched_gauss_newton_follows_the_reference_iterations(seed):
    """From the same start (the reference's linear solution) the batched iterations, with
    their per-epoch masks, end where the per-epoch loop does."""
    anchors, ranges = random_epochs(seed)
    for n in range(3, anchors.shape[1] + 1):
        usable = [_reference_usable(a, d) for a, d in zip(anchors, ranges)]
        group = [(a, d, _reference_linear(a, d)) for a, d in usable if len(d) == n]
        group = [(a, d, p) for a, d, p in group if p is not None]
        a, d, p = (np.stack(column) for column in zip(*group))
        expected = np.array([_reference_gauss_newton(*epoch) for epoch in group])
        np.testing.assert_allclose(lateration._gauss_newton(a, d, p), expected, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("seed", SEEDS)
def test_multilateration_batch_equals_the_per_epoch_forms(seed):
    """Exactly the per-epoch function (a batch of one) and, to 1e-6 m or 1e-7 relative, the
    reference: its LAPACK least squares and our SVD differ in the last bits, and the
    Gauss-Newton stopping test (the cost no longer falls) acts at rounding level, where the
    end is resolved to about sqrt(machine eps) ~ 1.5e-8 relative (~1e-8 m on a floor)."""
    anchors, ranges = random_epochs(seed)
    batch = multilateration_batch(anchors, ranges)
    np.testing.assert_array_equal(batch, _reference(multilateration, anchors, ranges))
    reference = _reference(_reference_multilateration, anchors, ranges)
    np.testing.assert_array_equal(np.isnan(batch), np.isnan(reference))
    np.testing.assert_allclose(batch, reference, rtol=1e-7, atol=1e-6)
    assert np.isnan(batch[:, 0]).sum() > 0 and np.isfinite(batch[:, 0]).sum() > len(batch) / 2


def test_degenerate_epochs_have_no_fix():
    anchors, ranges = random_epochs(0, epochs=45)
    fixes = multilateration_batch(anchors, ranges)
    no_fix = {0, 1, 2, 5, 8}                                       # collinear, 2 ranges, coincident, none
    for kind in (0, 1, 2, 3, 4, 5, 6, 8):                          # 7, nearly collinear, may go either way
        assert np.isnan(fixes[5 * kind]).all() == (kind in no_fix)
    assert fixes[30] == pytest.approx(anchors[30, 0], abs=1e-6)    # noise-free ranges, tag on anchor 0
    assert np.isfinite(min_max_batch(anchors, ranges)[5]).all()   # Min-Max solves a horizontal line


def test_empty_batches():
    assert min_max_batch(np.empty((0, 0, 2)), np.empty((0, 0))).shape == (0, 2)
    assert multilateration_batch(np.empty((3, 0, 2)), np.empty((3, 0))).shape == (3, 2)


# ---- batched epoch fixes -------------------------------------------------------------------
def test_smallest_per_epoch_keeps_the_k_smallest_of_each_epoch():
    anchors, ranges = random_epochs(3, width=9)
    ranges[::7, 4] = ranges[::7, 2]                                           # ties
    for k in (0, 3, 6, 20):
        xy, kept = smallest_per_epoch(anchors, ranges, k)
        for e in range(len(ranges)):
            keep = k_smallest(ranges[e], k or ranges.shape[1])
            np.testing.assert_array_equal(kept[e, :len(keep)], ranges[e, keep])
            np.testing.assert_array_equal(xy[e, :len(keep)], anchors[e, keep])
            assert not np.isfinite(kept[e, len(keep):]).any()


ANCHORS = {"A1": (0.0, 0.0), "A2": (20.0, 0.0), "A3": (20.0, 20.0), "A4": (0.0, 20.0), "A5": (10.0, 0.0),
           "A6": (5.0, 0.0), "A7": (9.0, 11.0)}                                # A1, A2, A5, A6 collinear
RSS = {k: RSS_MODEL[k] for k in ("p0_dbm", "path_loss_exponent", "sigma_db", "d0_m")}


def _per_epoch_fixes(data, p, technique):
    """The epoch loop before vectorisation: per epoch, k smallest distances, one solver call."""
    rss = RssParams(*(p[k] for k in ("p0_dbm", "path_loss_exponent", "sigma_db", "d0_m")))
    source = MeasurementSource(data, {"toa": "toa", "rss": "rss"}.get(technique, "hybrid"), p["anchors"], 1.0,
                               p["preliminary_filter"], p["max_range_m"], None if technique == "toa" else rss)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    solver, empty, out = {"minmax": min_max, "multilateration": multilateration}[p["solver"]], [], []
    for e in source.epochs(times, p["epoch_s"]):
        toa = source.horizontal_distances(e.range_ids, e.ranges, np.array(empty, dtype=object), np.array([]))
        nb = source.horizontal_distances(np.array(empty, dtype=object), np.array([]), e.rss_ids, e.rss)
        xy, d = {"toa": toa, "rss": nb, "fmix": (np.vstack([nb[0], toa[0]]), np.concatenate([nb[1], toa[1]]))}[
            technique]
        keep = k_smallest(d, p["k_smallest"] or len(d))
        out.append(solver(xy[keep], d[keep]))
    return _as_fixes(out)


@pytest.mark.parametrize("solver", ["minmax", "multilateration"])
@pytest.mark.parametrize("technique", ["toa", "rss", "fmix"])
@pytest.mark.parametrize("k", [0, 4])
def test_batched_epoch_fixes_equal_the_per_epoch_loop(solver, technique, k):
    """A walk with ranges to one random anchor at a time (epochs with 0 to 7 anchors, some
    only collinear ones) and RSS every second: the same fixes as the per-epoch loop."""
    rng = np.random.default_rng(18)
    times, ids = one_at_a_time(60.0, 12.0, rng, ANCHORS)
    tables = tables_for(times, ids, walk, ANCHORS, noise_m=0.3, rng=rng, rss_times=np.arange(1.0, 60.0, 1.0))
    tables["rss"]["rss_dbm"] += rng.normal(0, 2.0, len(tables["rss"]))
    data = run_data(tables)
    name, extra = ("fmix", {"solver": solver}) if technique == "fmix" else (solver, {"measurements": technique})
    p = registry.get(name).resolve({"k_smallest": k, "rss_calibration": "configured", **RSS, **extra})
    batched = registry.run(name, data, p)[["x", "y"]].to_numpy()
    expected = _per_epoch_fixes(data, dict(p, solver=solver), technique)
    np.testing.assert_array_equal(batched, expected)
    assert np.isnan(batched[:, 0]).any() and np.isfinite(batched[:, 0]).mean() > 0.3
