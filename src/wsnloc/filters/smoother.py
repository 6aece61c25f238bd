"""Fixed-interval Rauch-Tung-Striebel smoother over a stored forward pass (KF, EKF or UKF).

Inputs per step k = 0..N-1: the filtered mean x_k|k and covariance P_k|k, and the matrices
F_k, Q_k (and input B_k u_k) that predicted step k from step k-1 (F_0, Q_0 are not used;
a step the filter did not predict, e.g. a static epoch, has F = I, Q = 0, no input).
Backward pass, k = N-2 .. 0:
  x_k+1|k = F_k+1 x_k|k (+ B_k+1 u_k+1),   P_k+1|k = F_k+1 P_k|k F_k+1^T + Q_k+1
  C_k = P_k|k F_k+1^T P_k+1|k^-1
  x_k|N = x_k|k + C_k (x_k+1|N - x_k+1|k),  P_k|N = P_k|k + C_k (P_k+1|N - P_k+1|k) C_k^T
A P_k+1|k that is not positive definite (round-off after a regularised filter step) is
regularised before the solve (filters.numerics.regularise).
The motion model is linear, so recomputing the prediction from (F, Q) gives exactly the
filter's prediction; for an EKF/UKF the smoother is the linear RTS smoother around the
filtered estimates (the measurement non-linearity only enters through them).
"""

from __future__ import annotations

import numpy as np

from wsnloc.filters.numerics import regularise


def rts_smooth(xs, Ps, Fs, Qs, us=None, Bs=None) -> tuple[np.ndarray, np.ndarray]:
    """Smoothed means (N, n) and covariances (N, n, n).

    xs (N, n), Ps (N, n, n): filtered estimates; Fs (N, n, n), Qs (N, n, n): the prediction
    into each step (index 0 unused); us (N, k) and Bs (N, n, k): control inputs of those
    predictions, rows of us that are NaN (or us None) meaning no input.
    """
    xs = np.asarray(xs, dtype=float)
    Ps = np.asarray(Ps, dtype=float)
    Fs = np.asarray(Fs, dtype=float)
    Qs = np.asarray(Qs, dtype=float)
    N = len(xs)
    for name, arr in (("Ps", Ps), ("Fs", Fs), ("Qs", Qs)):
        if len(arr) != N:
            raise ValueError(f"rts_smooth: {name} has {len(arr)} steps, xs has {N}")
    x_s, P_s = xs.copy(), Ps.copy()
    for k in range(N - 2, -1, -1):
        F = Fs[k + 1]
        x_pred = F @ xs[k]
        if us is not None and np.all(np.isfinite(us[k + 1])):
            x_pred = x_pred + Bs[k + 1] @ us[k + 1]
        P_pred = F @ Ps[k] @ F.T + Qs[k + 1]
        try:
            C = np.linalg.solve(P_pred, F @ Ps[k]).T       # P_k F^T P_pred^-1 (P_pred symmetric)
        except np.linalg.LinAlgError:
            C = np.linalg.solve(regularise(P_pred), F @ Ps[k]).T
        x_s[k] = xs[k] + C @ (x_s[k + 1] - x_pred)
        P_s[k] = Ps[k] + C @ (P_s[k + 1] - P_pred) @ C.T
    return x_s, P_s
