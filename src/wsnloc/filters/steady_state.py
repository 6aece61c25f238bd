"""Position-only Kalman filters driven by dead-reckoning displacements (paper B).

State p = [x, y]; H = I.  Predict: p <- p + delta_DR, P <- P + Q.  Update with a fix z:
  classical:    K_k = P (P + R)^-1 (time-varying), P <- (I - K) P (I - K)^T + K R K^T
  steady state: K = P_inf (P_inf + R)^-1 constant, P_inf the a-priori solution of the
                discrete algebraic Riccati equation  P = P - P (P + R)^-1 P + Q
                (A = I, H = I), solved offline with scipy.linalg.solve_discrete_are.
Q is the process noise accumulated between two updates (per step Q times steps per update).
"""

from __future__ import annotations

import numpy as np


def steady_state_gain(Q, R) -> np.ndarray:
    """Constant gain K = P (P + R)^-1 with P the DARE solution for A = H = I."""
    from scipy.linalg import solve_discrete_are   # here: every estimator job imports this module

    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    R = np.atleast_2d(np.asarray(R, dtype=float))
    eye = np.eye(len(Q))
    P = solve_discrete_are(eye, eye, Q, R)     # a-priori steady-state covariance
    return P @ np.linalg.inv(P + R)


def fuse(displacements: np.ndarray, fixes: np.ndarray, start, Q_step, R, gain=None, P0=None) -> np.ndarray:
    """Run the filter over N steps.

    displacements: (N, 2) dead-reckoning displacement of each step (m); fixes: (N, 2) fix
    available at the end of the step, NaN when none; start: initial position. With `gain`
    the steady-state filter runs; otherwise the classical filter from covariance P0.
    Returns (N + 1, 2) positions (start included).
    """
    p = np.asarray(start, dtype=float).copy()
    Q_step = np.asarray(Q_step, dtype=float)
    R = np.asarray(R, dtype=float)
    P = np.zeros((2, 2)) if P0 is None else np.asarray(P0, dtype=float).copy()
    out = np.empty((len(displacements) + 1, 2))
    out[0] = p
    eye = np.eye(2)
    for k, (delta, z) in enumerate(zip(displacements, fixes)):
        p = p + delta
        P = P + Q_step
        if np.all(np.isfinite(z)):
            if gain is None:
                K = P @ np.linalg.inv(P + R)
                P = (eye - K) @ P @ (eye - K).T + K @ R @ K.T
            else:
                K = gain
            p = p + K @ (z - p)
        out[k + 1] = p
    return out
