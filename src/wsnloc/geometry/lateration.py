"""Position from ranges to known anchors: Min-Max and multilateration (paper D).

Both return None ("no fix") with fewer than 3 usable ranges or a degenerate geometry,
never raise on such input. Non-finite or negative ranges are dropped first.
"""

from __future__ import annotations

import numpy as np

MIN_RANGES = 3
MAX_CONDITION = 1e8          # linear system worse than this: anchors (nearly) collinear
GAUSS_NEWTON_STEPS = 10


def _usable(anchors, ranges) -> tuple[np.ndarray, np.ndarray]:
    anchors = np.asarray(anchors, dtype=float).reshape(-1, 2)
    ranges = np.asarray(ranges, dtype=float).reshape(-1)
    keep = np.isfinite(ranges) & (ranges >= 0) & np.all(np.isfinite(anchors), axis=1)
    return anchors[keep], ranges[keep]


def min_max(anchors, ranges) -> np.ndarray | None:
    """Centre of the intersection of the boxes [x_i - d_i, x_i + d_i] x [y_i - d_i, y_i + d_i].

    Lower corner = max over i of (x_i - d_i, y_i - d_i); upper corner = min over i of
    (x_i + d_i, y_i + d_i); estimate = (lower + upper) / 2. With inconsistent ranges the
    "intersection" may be empty (lower > upper); its centre is still returned, as in the
    paper. Anchors all on one vertical or horizontal line are still solvable by Min-Max.
    """
    a, d = _usable(anchors, ranges)
    if len(d) < MIN_RANGES:
        return None
    lower = np.max(a - d[:, None], axis=0)
    upper = np.min(a + d[:, None], axis=0)
    return (lower + upper) / 2.0


def _linear_solution(a: np.ndarray, d: np.ndarray) -> np.ndarray | None:
    """Least squares on the circles linearised by subtracting the last equation.

    (x - x_i)^2 + (y - y_i)^2 = d_i^2 minus the same for anchor L gives
    2 (x_L - x_i) x + 2 (y_L - y_i) y = d_i^2 - d_L^2 - |a_i|^2 + |a_L|^2.
    """
    ref, d_ref = a[-1], d[-1]
    matrix = 2.0 * (ref[None, :] - a[:-1])
    rhs = d[:-1] ** 2 - d_ref**2 - np.sum(a[:-1] ** 2, axis=1) + np.sum(ref**2)
    if np.linalg.cond(matrix) > MAX_CONDITION:
        return None
    solution, *_ = np.linalg.lstsq(matrix, rhs, rcond=None)
    return solution


def multilateration(anchors, ranges, refine: bool = True) -> np.ndarray | None:
    """Linearised least squares, then Gauss-Newton on sum_i (||p - a_i|| - d_i)^2.

    Gauss-Newton: J_i = (p - a_i)^T / ||p - a_i||, p <- p - (J^T J)^-1 J^T r with
    r_i = ||p - a_i|| - d_i; the 2 x 2 normal equations are solved by Cramer's rule (a
    singular J^T J ends the iterations); a step that does not lower the cost is not taken.
    Returns None for fewer than 3 ranges or (nearly) collinear anchors.
    """
    a, d = _usable(anchors, ranges)
    if len(d) < MIN_RANGES:
        return None
    p = _linear_solution(a, d)
    if p is None or not refine:
        return p

    diff = p - a
    dist = np.hypot(diff[:, 0], diff[:, 1])
    current = float(np.sum((dist - d) ** 2))
    for _ in range(GAUSS_NEWTON_STEPS):
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


LOCALIZERS = {"minmax": min_max, "multilateration": multilateration}
