"""Position from ranges to known anchors: Min-Max and multilateration (paper D).

Each solver exists in a batched form (`*_batch`: many epochs at once, one fix per epoch,
NaN rows for "no fix") and a per-epoch form (one epoch; None for "no fix") that is a
thin call of the batched one. An epoch has no fix with fewer than 3 usable ranges or a
degenerate geometry; neither form raises on such input. Usable ranges are finite, >= 0
and to anchors with finite coordinates; the others (NaN padding included) are ignored.
"""

from __future__ import annotations

import numpy as np

MIN_RANGES = 3
MAX_CONDITION = 1e8          # linear system worse than this: anchors (nearly) collinear
GAUSS_NEWTON_STEPS = 10
MIN_STEP_M = 1e-9            # Gauss-Newton stops after a step shorter than this (m)
MIN_DISTANCE_M = 1e-9        # distances below this (m) are clipped in the Jacobian


def _usable(anchors: np.ndarray, ranges: np.ndarray) -> np.ndarray:
    """(epochs, m) mask of the usable ranges: finite, >= 0, to an anchor with finite x, y."""
    return np.isfinite(ranges) & (ranges >= 0) & np.all(np.isfinite(anchors), axis=-1)


def _as_batch(anchors, ranges) -> tuple[np.ndarray, np.ndarray]:
    """anchors (epochs, m, 2) [m] and ranges (epochs, m) [m] as float arrays."""
    ranges = np.asarray(ranges, dtype=float)
    anchors = np.asarray(anchors, dtype=float).reshape(*ranges.shape, 2)
    return anchors, ranges


def _one_epoch(batch_solver, anchors, ranges, **options) -> np.ndarray | None:
    """A batched solver on one epoch: its fix (2,) [m], None where the batch has a NaN row."""
    ranges = np.asarray(ranges, dtype=float).reshape(1, -1)
    fix = batch_solver(np.asarray(anchors, dtype=float).reshape(1, -1, 2), ranges, **options)[0]
    return fix if np.all(np.isfinite(fix)) else None


def min_max_batch(anchors, ranges) -> np.ndarray:
    """Per epoch, the centre of the intersection of the boxes [x_i - d_i, x_i + d_i] x [y_i - d_i, y_i + d_i].

    anchors (epochs, m, 2) [m], ranges (epochs, m) [m] -> fixes (epochs, 2) [m].
    Lower corner = max over the usable i of (x_i - d_i, y_i - d_i); upper corner = min over
    them of (x_i + d_i, y_i + d_i); estimate = (lower + upper) / 2. With inconsistent ranges
    the "intersection" may be empty (lower > upper); its centre is still returned, as in the
    paper. Anchors all on one vertical or horizontal line are still solvable by Min-Max.
    NaN row: fewer than 3 usable ranges.
    """
    a, d = _as_batch(anchors, ranges)
    usable = _usable(a, d)
    keep = usable[..., None]
    with np.errstate(invalid="ignore"):            # inf - inf of unusable entries, masked below
        lower = np.max(np.where(keep, a - d[..., None], -np.inf), axis=1, initial=-np.inf)
        upper = np.min(np.where(keep, a + d[..., None], np.inf), axis=1, initial=np.inf)
        fixes = (lower + upper) / 2.0
    fixes[usable.sum(axis=1) < MIN_RANGES] = np.nan
    return fixes


def min_max(anchors, ranges) -> np.ndarray | None:
    """Min-Max (min_max_batch) on one epoch: anchors (m, 2), ranges (m,) [m] -> (2,) or None."""
    return _one_epoch(min_max_batch, anchors, ranges)


def _linear_solution(a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Least squares on the circles linearised by subtracting the last equation, per epoch.

    a (epochs, n, k), d (epochs, n) [m], all usable -> (epochs, k) [m] (k = 2, or 3 in space:
    the same equations with z), NaN rows where the
    system's condition number s_max / s_min exceeds MAX_CONDITION (anchors (nearly) collinear).
    (x - x_i)^2 + (y - y_i)^2 = d_i^2 minus the same for anchor L = n gives
    2 (x_L - x_i) x + 2 (y_L - y_i) y = d_i^2 - d_L^2 - |a_i|^2 + |a_L|^2, i < L, solved as
    A p = b by the SVD A = U S V^T: p = V S^-1 U^T b.
    """
    ref, d_ref = a[:, -1], d[:, -1:]
    matrix = 2.0 * (ref[:, None, :] - a[:, :-1])
    rhs = d[:, :-1] ** 2 - d_ref**2 - np.sum(a[:, :-1] ** 2, axis=2) + np.sum(ref**2, axis=1)[:, None]
    u, s, vt = np.linalg.svd(matrix, full_matrices=False)
    ok = (s[:, -1] > 0) & (s[:, -1] * MAX_CONDITION >= s[:, 0])        # s_max / s_min <= MAX_CONDITION
    projected = np.einsum("eij,ei->ej", u[ok], rhs[ok]) / s[ok]
    solution = np.full((len(a), a.shape[-1]), np.nan)
    solution[ok] = np.einsum("eji,ej->ei", vt[ok], projected)
    return solution


def _gauss_newton_step(diff: np.ndarray, dist: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Gauss-Newton step (epochs, 2) [m] on r_i = ||p - a_i|| - d_i; NaN rows where J^T J is singular.

    diff = p - a_i (epochs, n, 2), dist = ||p - a_i|| (epochs, n), d (epochs, n) [m].
    J_i = (p - a_i)^T / max(||p - a_i||, MIN_DISTANCE_M); step = (J^T J)^-1 J^T r by
    Cramer's rule on the 2 x 2 normal equations.
    """
    safe = np.maximum(dist, MIN_DISTANCE_M)
    jac_t = np.swapaxes(diff / safe[..., None], 1, 2)                      # J^T (epochs, 2, n)
    normal = np.matmul(jac_t, np.swapaxes(jac_t, 1, 2))                     # J^T J (epochs, 2, 2)
    jxx, jxy, jyy = normal[:, 0, 0], normal[:, 0, 1], normal[:, 1, 1]
    gx, gy = np.matmul(jac_t, (safe - d)[..., None])[..., 0].T             # J^T r
    det = jxx * jyy - jxy * jxy
    step = np.empty((len(d), 2))
    step[:, 0], step[:, 1] = jyy * gx - jxy * gy, jxx * gy - jxy * gx
    regular = (np.isfinite(det) & (det != 0.0))[:, None]
    return np.divide(step, det[:, None], out=np.full_like(step, np.nan), where=regular)


def _distances(p: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """p - a_i (epochs, n, 2) and ||p - a_i|| (epochs, n) [m] for p (epochs, 2)."""
    diff = p[:, None, :] - a
    return diff, np.hypot(diff[..., 0], diff[..., 1])


def _gauss_newton(a: np.ndarray, d: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Gauss-Newton from p (epochs, 2) on the cost sum_i (||p - a_i|| - d_i)^2, per epoch.

    At most GAUSS_NEWTON_STEPS steps p <- p - step (_gauss_newton_step). An epoch stops at
    a step that does not lower its cost (not taken; a singular J^T J gives a NaN step,
    never taken) or after a taken step shorter than MIN_STEP_M; the working arrays keep the
    epochs still iterating (per-epoch convergence mask).
    """
    p = p.copy()
    rows = np.arange(len(p))
    diff, dist = _distances(p, a)
    cost = np.sum((dist - d) ** 2, axis=1)
    for _ in range(GAUSS_NEWTON_STEPS):
        step = _gauss_newton_step(diff, dist, d)
        candidate = p[rows] - step
        candidate_diff, candidate_dist = _distances(candidate, a)
        new = np.sum((candidate_dist - d) ** 2, axis=1)
        taken = new < cost
        p[rows[taken]] = candidate[taken]
        go_on = taken & (np.hypot(step[:, 0], step[:, 1]) >= MIN_STEP_M)
        rows, a, d, cost = rows[go_on], a[go_on], d[go_on], new[go_on]
        diff, dist = candidate_diff[go_on], candidate_dist[go_on]
        if rows.size == 0:
            break
    return p


def _compact(a: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The usable ranges of each epoch moved to its front in their order: (a, d, counts)."""
    keep = _usable(a, d)
    order = np.argsort(~keep, axis=1, kind="stable")
    return (np.take_along_axis(a, order[..., None], axis=1), np.take_along_axis(d, order, axis=1),
            keep.sum(axis=1))


def multilateration_batch(anchors, ranges, refine: bool = True) -> np.ndarray:
    """Per epoch, linearised least squares (_linear_solution), then Gauss-Newton (_gauss_newton)
    on sum_i (||p - a_i|| - d_i)^2 over its usable ranges, in their given order.

    anchors (epochs, m, 2) [m], ranges (epochs, m) [m] -> fixes (epochs, 2) [m]. Epochs with
    the same number n of usable ranges are solved together. NaN row: fewer than 3 usable
    ranges or (nearly) collinear anchors.
    """
    a, d, counts = _compact(*_as_batch(anchors, ranges))
    fixes = np.full((len(d), 2), np.nan)
    for n in np.unique(counts[counts >= MIN_RANGES]):
        rows = np.flatnonzero(counts == n)
        a_n, d_n = a[rows, :n], d[rows, :n]
        p = _linear_solution(a_n, d_n)
        solved = np.flatnonzero(np.all(np.isfinite(p), axis=1))
        if refine:
            p[solved] = _gauss_newton(a_n[solved], d_n[solved], p[solved])
        fixes[rows] = p
    return fixes


def multilateration(anchors, ranges, refine: bool = True) -> np.ndarray | None:
    """Multilateration (multilateration_batch) on one epoch: anchors (m, 2), ranges (m,) [m]
    -> (2,) [m], None for fewer than 3 usable ranges or (nearly) collinear anchors."""
    return _one_epoch(multilateration_batch, anchors, ranges, refine=refine)


def multilateration_3d(anchors, ranges) -> np.ndarray | None:
    """3-D multilateration on one epoch: anchors (m, 3), ranges (m,) [m] -> (3,) [m].

    The linearised least squares of _linear_solution in 3-D, refined by Gauss-Newton
    (Levenberg-Marquardt, scipy.optimize.least_squares) on sum_i (||p - a_i|| - d_i)^2.
    None with fewer than 4 usable ranges or anchors (nearly) in one plane (the height is
    then not observable from the linear system)."""
    from scipy.optimize import least_squares

    a, d = np.asarray(anchors, dtype=float).reshape(-1, 3), np.asarray(ranges, dtype=float).ravel()
    keep = _usable(a, d)
    a, d = a[keep], d[keep]
    if len(d) < MIN_RANGES + 1:
        return None
    p = _linear_solution(a[None], d[None])[0]
    if not np.all(np.isfinite(p)):
        return None
    refined = least_squares(lambda q: np.sqrt(np.sum((q - a) ** 2, axis=1)) - d, p, method="lm",
                            xtol=MIN_STEP_M)
    return refined.x if np.all(np.isfinite(refined.x)) else p


LOCALIZERS = {"minmax": min_max_batch, "multilateration": multilateration_batch}


CENTROID_NEAREST = 3


def weighted_centroid(anchors, distances, k: int = CENTROID_NEAREST) -> np.ndarray | None:
    """Weighted centroid of the k nearest anchors, weights 1 / d (Blumenthal et al. 2007, degree 1):
    sum_i a_i / d_i / sum_i 1 / d_i over the k smallest finite distances d_i (m); None without one.
    Always inside the anchors' hull: a bounded start where multilateration on distances as
    uncertain as RSS-inverted ones (a factor of 2 at 6 dB shadowing) can land tens of metres off."""
    a, d = np.asarray(anchors, dtype=float).reshape(-1, 2), np.asarray(distances, dtype=float)
    usable = np.flatnonzero(np.isfinite(d) & (d >= 0))
    if not len(usable):
        return None
    nearest = usable[np.argsort(d[usable], kind="stable")][:k]
    w = 1.0 / np.maximum(d[nearest], MIN_DISTANCE_M)
    return (a[nearest] * w[:, None]).sum(0) / w.sum()
