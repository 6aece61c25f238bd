"""Sliding-window batch estimator on a run's ranges (filters.sliding_window).

At every output time t_k of the run's grid, the ranges measured in [t_k - W, t_k] (each at
its own time, to its anchor, 3-D with the anchor's height difference) are solved jointly
by robust non-linear least squares over constant-velocity knots, warm-started from, and
weakly tied to, the previous window; the estimate is the last knot's position and its
covariance (see filters.sliding_window for the residuals and the loss).
Initiator: the first window with at least 4 ranges spread over at least one knot interval
(so that the knots' velocity is observable: ranges at a single time leave it free and
the normal equations singular) whose per-anchor means give a multilateration fix starts
there at rest. Coasting limit (core.CoastingDeleter): after `max_coast_s` seconds
without a range, or with ranges of one anchor alone (core.Support: a distance, not a position),
the solution is dropped (counted as a reset) and restarted by the initiator;
so is a window whose least squares do not converge (filters.least_squares.ConvergenceError)
or whose prior, the previous window's covariance, is numerically singular (on real data with
poor geometry, e.g. range differences far from a small anchor cluster), or whose solution is
not finite or further than max_range_m from every anchor (no range could reach it: range
differences from four anchors within 3 m, the target outside them, ran off along the
hyperbolae' asymptotes to 1e7 m): such a window is counted in attrs `skipped`; covariances
that are not positive definite where a factor is needed are regularised (filters.numerics,
attrs `regularised`). A window that holds no measurement is neither solved nor output (the next
window starts from the last solution; an extrapolation: a reviewer's run with 20-100 s gaps had
57 such outputs, up to 97 m off), counted in attrs `withheld`.
Range differences (`measurements: tdoa`, estimators.tdoa.TdoaSource): each group of records
sharing a time stamp is one factor block with its TdoaModel's correlated noise (whitened by
its Cholesky factor), and the initiator's fix is the hyperbolic solver's.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.estimators.core import COLUMNS, CoastingDeleter, Support, Track, beyond_reach
from wsnloc.estimators.measurements import MeasurementSource
from wsnloc.estimators.run_data import RunData
from wsnloc.estimators.tdoa import TdoaSource
from wsnloc.filters.least_squares import ConvergenceError
from wsnloc.filters.numerics import Guards, usable
from wsnloc.filters.sliding_window import STATE, SlidingWindowEstimator


def _block_diagonal(blocks: list[np.ndarray]) -> np.ndarray:
    out = np.zeros((sum(len(b) for b in blocks),) * 2)
    k = 0
    for b in blocks:
        out[k:k + len(b), k:k + len(b)] = b
        k += len(b)
    return out


def _differences(source: TdoaSource, a: int, b: int) -> tuple:
    """The range differences of records a..b-1 as window factors: (t, anchors (k, 2), dz, values,
    (reference anchors, their dz, W)), W block-diagonal over the time groups, W_g = L_g^-1 with
    L_g L_g^T the group's TdoaModel R (redundant pairs left out, estimators.tdoa)."""
    records = source.records()
    starts = records.groups()[:-1]
    bounds = np.r_[starts[(starts >= a) & (starts < b)], b]      # a and b are group bounds (searchsorted)
    parts = []
    for g, h in zip(bounds[:-1], bounds[1:]):
        model = source.model(*records.split(g, h))
        tdoa = model.parts[0]
        dz = np.zeros(len(tdoa.receivers)) if tdoa.dz_m is None else tdoa.dz_m
        i, j = tdoa.pairs[:, 0], tdoa.pairs[:, 1]
        parts.append((np.full(len(i), records.t[g]), tdoa.receivers[i], dz[i], model.z, tdoa.receivers[j], dz[j],
                      np.linalg.inv(np.linalg.cholesky(model.R()))))
    t, anchors, dz, values, ref, ref_dz, whiten = zip(*parts)
    return (np.concatenate(t), np.vstack(anchors), np.concatenate(dz), np.concatenate(values),
            (np.vstack(ref), np.concatenate(ref_dz), _block_diagonal(list(whiten))))


def sliding_window(data: RunData, p: dict) -> pd.DataFrame:
    """Estimates (core.COLUMNS; n_meas = ranges or range differences in the window, nis NaN) of one run."""
    tdoa = p["measurements"] == "tdoa"
    source = TdoaSource(data, p["anchors"], p["range_sigma_m"], p["max_range_m"]) if tdoa else \
        MeasurementSource(data, "toa", p["anchors"], p["range_sigma_m"], p["preliminary_filter"], p["max_range_m"],
                          None)
    records = source.records()
    anchors_xy = None if tdoa else data.positions(records.anchor)
    dz = None if tdoa else data.height_offsets(records.anchor)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    window = p["window_s"]
    deleter = CoastingDeleter(p["max_coast_s"])
    members = data.subset_positions(p["anchors"])
    rows, resets, solver, support, seen, withheld, guards = [], 0, None, None, 0, 0, Guards()
    for t_k in times:
        a = int(np.searchsorted(records.t, t_k - window, side="left"))
        b = int(np.searchsorted(records.t, t_k, side="right"))
        if solver is not None:
            for j in range(seen, b):
                support.use(records.anchor[j:j + 1], records.t[j])
            if deleter.delete(t_k, support.since, False):
                solver, resets = None, resets + 1
        seen = b
        initial = None
        if solver is None:
            spread = b - a >= STATE and records.t[b - 1] - records.t[a] >= p["knot_s"]
            fix = source.fix(*records.window_means(a, b)) if spread else None
            if fix is None:
                continue
            solver = SlidingWindowEstimator(window, p["knot_s"], p["accel_sigma_mps2"], p["loss"], p["f_scale"],
                                            p["prior_inflation"], guards)
            initial, support = np.array([fix[0], fix[1], 0.0, 0.0]), Support(t_k)
        if b == a:                      # no measurement in the window: an extrapolation, not solved nor output
            withheld += 1
            continue
        try:
            if tdoa:
                t, xy, h, value, differences = _differences(source, a, b)
                estimate = solver.estimate(t_k, t, xy, h, value, p["range_sigma_m"], initial, differences)
            else:
                estimate = solver.estimate(t_k, records.t[a:b], anchors_xy[a:b], dz[a:b], records.value[a:b],
                                           p["range_sigma_m"], initial)
        except (ConvergenceError, np.linalg.LinAlgError):   # a window the solver cannot settle, or whose
            estimate = None         # previous solution's covariance is numerically singular
        if estimate is None or not usable(estimate.x, estimate.P) \
                or beyond_reach(estimate.x[None, :2], members, p["max_range_m"])[0]:   # drop the solution (a reset)
            guards.skipped += 1
            solver, resets = None, resets + 1
            continue
        P = estimate.P
        rows.append((t_k, estimate.x[0], estimate.x[1], P[0, 0], P[0, 1], P[1, 1], estimate.n_ranges, np.nan))
    return Track(np.array(rows, dtype=float).reshape(len(rows), len(COLUMNS)),
                 {"resets": resets, "withheld": withheld, **guards.attrs()}).frame()
