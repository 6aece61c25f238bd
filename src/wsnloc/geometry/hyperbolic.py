"""Position from range differences (TDOA) to known receivers: Chan's closed form, refined by
Gauss-Newton on the range differences.

Pairs (a_i, b_i) of receivers with measured range differences D_i = r_{a_i} - r_{b_i} (m),
r_j = sqrt(|p - a_j|^2 + dz_j^2) (dz_j the receiver's height above the tag; 0 in 2-D).

Closed form (Chan & Ho 1994, first stage), for the pairs sharing the most frequent reference b:
r_i = r_b + D_i squared, minus r_b^2, is linear in (x, y, r_b):
    2 (a_i - b) . p + 2 D_i r_b = |a_i|^2 + dz_i^2 - |b|^2 - dz_b^2 - D_i^2,
solved by least squares with at least 3 pairs (r_b is a third unknown; Chan's second stage,
which enforces r_b = |p - b|, is replaced by the Gauss-Newton refinement below). Exact on
noise-free data.
Gauss-Newton on all pairs: minimise (z - h(p))^T R^-1 (z - h(p)) with the TDOA model's h,
Jacobian and correlated noise R (filters.measurement_models.TdoaModel), from the closed-form
point and from the receivers' centroid; the lower cost wins. Steps are halved while they
raise the cost.
No fix (None): fewer than 2 pairs, a non-finite result, or a point farther than
`max_range_m` from every receiver (a hyperbola's far branch: with receivers close together
the range differences fix the bearing much better than the distance, see docs/estimators.md).
"""

from __future__ import annotations

import numpy as np

from wsnloc.filters.measurement_models import TdoaModel

MIN_PAIRS = 2
ITERATIONS = 30
MIN_STEP_M = 1e-10
MAX_CONDITION = 1e10


def chan_closed_form(model: TdoaModel, z: np.ndarray) -> np.ndarray | None:
    """(x, y) from the pairs sharing the most frequent reference (module docstring); None
    with fewer than 3 such pairs or a (nearly) singular system."""
    refs, counts = np.unique(model.pairs[:, 1], return_counts=True)
    b = refs[np.argmax(counts)]
    rows = np.flatnonzero(model.pairs[:, 1] == b)
    if len(rows) < 3:
        return None
    dz = np.zeros(len(model.receivers)) if model.dz_m is None else np.asarray(model.dz_m, dtype=float)
    a, d = model.pairs[rows, 0], np.asarray(z, dtype=float)[rows]
    pos, ref = model.receivers[a], model.receivers[b]
    A = np.column_stack([2.0 * (pos - ref), 2.0 * d])
    rhs = np.sum(pos**2, axis=1) + dz[a] ** 2 - ref @ ref - dz[b] ** 2 - d**2
    s = np.linalg.svd(A, compute_uv=False)
    if s[-1] <= 0 or s[0] > MAX_CONDITION * s[-1]:
        return None
    solution = np.linalg.lstsq(A, rhs, rcond=None)[0]
    return solution[:2] if np.all(np.isfinite(solution)) else None


def _cost(model: TdoaModel, z: np.ndarray, R_inv: np.ndarray, p: np.ndarray) -> float:
    r = z - model.h(p)
    return float(r @ R_inv @ r)


def gauss_newton(model: TdoaModel, z: np.ndarray, p0: np.ndarray) -> tuple[np.ndarray, float]:
    """(position, cost) of Gauss-Newton on the whitened range differences from p0 (m)."""
    R_inv = np.linalg.inv(model.R())
    W = np.linalg.cholesky(R_inv).T                 # W^T W = R^-1: whitening
    p = np.asarray(p0, dtype=float)[:2].copy()
    cost = _cost(model, z, R_inv, p)
    for _ in range(ITERATIONS):
        step = np.linalg.lstsq(W @ model.jacobian(p), W @ (z - model.h(p)), rcond=None)[0]
        for _ in range(30):                          # halve while the cost rises
            trial = _cost(model, z, R_inv, p + step)
            if trial <= cost:
                break
            step = step / 2.0
        else:
            break
        p, cost = p + step, trial
        if np.hypot(*step) < MIN_STEP_M:
            break
    return p, cost


def tdoa_fix(model: TdoaModel, z, max_range_m: float = np.inf) -> np.ndarray | None:
    """Position (2,) in m from range differences z (m,) with the model's pairs (module docstring)."""
    z = np.asarray(z, dtype=float)
    if len(z) < MIN_PAIRS or not np.all(np.isfinite(z)):
        return None
    starts = [model.receivers[np.unique(model.pairs)].mean(axis=0)]
    closed = chan_closed_form(model, z)
    if closed is not None:
        starts.insert(0, closed)
    p, _ = min((gauss_newton(model, z, start) for start in starts), key=lambda result: result[1])
    if not np.all(np.isfinite(p)):
        return None
    nearest = np.min(np.hypot(*(model.receivers - p).T))
    return p if nearest <= max_range_m else None
