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
without a range the solution is dropped (counted as a reset) and restarted by the initiator.
Real data (filters.numerics): covariances that are not positive definite are regularised;
a window whose solution is not finite is skipped and the solution restarted (a reset); both
counted in attrs `regularised` and `skipped`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.estimators.core import COLUMNS, CoastingDeleter, Track
from wsnloc.estimators.measurements import MeasurementSource
from wsnloc.estimators.run_data import RunData
from wsnloc.filters.numerics import Guards, usable
from wsnloc.filters.sliding_window import STATE, SlidingWindowEstimator


def sliding_window(data: RunData, p: dict) -> pd.DataFrame:
    """Estimates (core.COLUMNS; n_meas = ranges in the window, nis NaN) of one run."""
    source = MeasurementSource(data, "toa", p["anchors"], p["range_sigma_m"], p["preliminary_filter"],
                               p["max_range_m"], None)
    records = source.records()
    anchors_xy, dz = data.positions(records.anchor), data.height_offsets(records.anchor)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    window = p["window_s"]
    deleter = CoastingDeleter(p["max_coast_s"])
    rows, resets, solver, last_range, guards = [], 0, None, -np.inf, Guards()
    for t_k in times:
        a = int(np.searchsorted(records.t, t_k - window, side="left"))
        b = int(np.searchsorted(records.t, t_k, side="right"))
        if b > a:
            last_range = records.t[b - 1]
        if solver is not None and deleter.delete(t_k, last_range, False):
            solver, resets = None, resets + 1
        initial = None
        if solver is None:
            spread = b - a >= STATE and records.t[b - 1] - records.t[a] >= p["knot_s"]
            fix = source.fix(*records.window_means(a, b)) if spread else None
            if fix is None:
                continue
            solver = SlidingWindowEstimator(window, p["knot_s"], p["accel_sigma_mps2"], p["loss"], p["f_scale"],
                                            p["prior_inflation"], guards)
            initial = np.array([fix[0], fix[1], 0.0, 0.0])
        estimate = solver.estimate(t_k, records.t[a:b], anchors_xy[a:b], dz[a:b], records.value[a:b],
                                   p["range_sigma_m"], initial)
        if not usable(estimate.x, estimate.P):
            guards.skipped += 1
            solver, resets = None, resets + 1
            continue
        P = estimate.P
        rows.append((t_k, estimate.x[0], estimate.x[1], P[0, 0], P[0, 1], P[1, 1], estimate.n_ranges, np.nan))
    return Track(np.array(rows, dtype=float).reshape(len(rows), len(COLUMNS)), {"resets": resets, **guards.attrs()}).frame()
