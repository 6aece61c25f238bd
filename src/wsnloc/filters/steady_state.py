"""Position-only Kalman filters driven by dead-reckoning displacements (paper B).

State p = [x, y]; H = I.  Predict: p <- p + delta_DR, P <- P + Q.  Update with a fix z:
  classical:    K_k = P (P + R)^-1 (time-varying), P <- (I - K) P (I - K)^T + K R K^T
  steady state: K = P_inf (P_inf + R)^-1 constant, P_inf the a-priori solution of the
                discrete algebraic Riccati equation  P = P - P (P + R)^-1 P + Q
                (A = I, H = I), solved offline with scipy.linalg.solve_discrete_are.
Q is the process noise accumulated between two updates (per step Q times steps per update).

The classical filter is filters.kalman's predict and update (joseph_update) with F = H = I and
the displacement as the input term. With a diagonal gain (paper B: sigma^2 I) the steady-state
filter is two independent scalar filters, one per axis, run in plain floats: per axis
  p <- p + d;  on a fix  p <- p + k (z - p),
the operations (and their order) of the matrix products on a diagonal gain, so the positions
are bitwise those of the 2 x 2 matrix recursion (tests/test_paper_b.py).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from wsnloc.filters.kalman import joseph_update, predict
from wsnloc.filters.numerics import Guards


def steady_state_gain(Q, R) -> np.ndarray:
    """Constant gain K = P (P + R)^-1 with P the DARE solution for A = H = I (a copy of the
    solution cached per (Q, R): the Monte Carlo runs of a setting share it)."""
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    R = np.atleast_2d(np.asarray(R, dtype=float))
    return _dare_gain(len(Q), tuple(Q.ravel()), tuple(R.ravel())).copy()


@lru_cache(maxsize=64)
def _dare_gain(n: int, q: tuple, r: tuple) -> np.ndarray:
    """steady_state_gain of the n x n matrices given by their row-major entries."""
    from scipy.linalg import solve_discrete_are   # here: every estimator job imports this module

    Q, R = np.reshape(q, (n, n)), np.reshape(r, (n, n))
    eye = np.eye(n)
    P = solve_discrete_are(eye, eye, Q, R)     # a-priori steady-state covariance
    return P @ np.linalg.inv(P + R)


def fuse(displacements: np.ndarray, fixes: np.ndarray, start, Q_step, R, gain=None, P0=None,
         guards: Guards | None = None) -> np.ndarray:
    """Run the filter over N steps.

    displacements: (N, 2) dead-reckoning displacement of each step (m); fixes: (N, 2) fix
    available at the end of the step, NaN when none (a fix is used when both coordinates
    are finite); start: initial position. With `gain` the steady-state filter runs;
    otherwise the classical filter from covariance P0 (default 0), whose updates that are not
    finite are skipped (the prior kept) and counted in guards.skipped (filters.numerics). Q_step,
    R, P0 in m^2; the gain must be diagonal (one scalar filter per axis). Returns (N + 1, 2)
    positions (m), start included.
    """
    displacements, fixes = np.asarray(displacements, dtype=float), np.asarray(fixes, dtype=float)
    has_fix = np.isfinite(fixes).all(axis=1)
    start = np.asarray(start, dtype=float)
    if gain is None:
        return _classical(displacements, fixes, has_fix, start, np.asarray(Q_step, dtype=float),
                          np.asarray(R, dtype=float), np.zeros((2, 2)) if P0 is None else np.asarray(P0, dtype=float),
                          Guards() if guards is None else guards)
    k = _diagonal(gain, "gain")
    out = np.empty((len(displacements) + 1, 2))
    for axis in range(2):
        out[:, axis] = _steady_axis(displacements[:, axis].tolist(), fixes[:, axis].tolist(), has_fix.tolist(),
                                    float(start[axis]), k[axis])
    return out


def _diagonal(matrix, name: str) -> list[float]:
    """The diagonal of a 2 x 2 diagonal matrix (zeros for None); ValueError if not diagonal."""
    m = np.zeros((2, 2)) if matrix is None else np.asarray(matrix, dtype=float)
    if m.shape != (2, 2) or m[0, 1] != 0 or m[1, 0] != 0:
        raise ValueError(f"fuse: {name} must be a diagonal 2 x 2 matrix (one scalar filter per axis)")
    return np.diag(m).tolist()


def _steady_axis(deltas: list, fixes: list, has_fix: list, p: float, k: float) -> list[float]:
    """One axis of the steady-state filter: p <- p + d; on a fix p <- p + k (z - p)."""
    out = [p]
    for delta, z, fix in zip(deltas, fixes, has_fix):
        p += delta
        if fix:
            p += k * (z - p)
        out.append(p)
    return out


def _classical(displacements: np.ndarray, fixes: np.ndarray, has_fix: np.ndarray, start: np.ndarray,
               Q_step: np.ndarray, R: np.ndarray, P0: np.ndarray, guards: Guards) -> np.ndarray:
    """The classical filter (module docstring): predict with the step's displacement, then the
    Kalman update (joseph_update, H = I) where the step has a fix, a non-finite one skipped and
    counted in guards.skipped; (N + 1, 2) positions (m)."""
    eye = np.eye(2)
    x, P = start.copy(), P0.copy()
    out = [x]
    for delta, z, fix in zip(displacements, fixes, has_fix):
        x, P = predict(x, P, eye, Q_step, delta)
        if fix:
            new = joseph_update(x, P, z - x, eye, R)
            x, P = new.x, new.P
            guards.skipped += int(not new.ok)
        out.append(x)
    return np.array(out)
