"""Range self-calibration: the filter state augmented with a common range scale and/or offset.

Measured range of anchor i:  r_i = s d_i(x) + b + v_i,  with d_i(x) the (3-D) geometric
range of the position, s the common scale (1 = no error) and b the common offset (m).
The augmented state is [motion state, s, b] (only the modes' entries):
  h_i(x, s, b) = s d_i(x) + b,
  dh_i/dx = s dd_i/dx,  dh_i/ds = d_i(x),  dh_i/db = 1.
s and b are constants (F = I on them, no process noise). They are observable while the
target moves among >= 4 anchors: a scale (or offset) error cannot be absorbed by the
position then, unlike with 3 anchors, where a common offset shifts every fix alike. RSS
rows of a hybrid model are left as they are (zero columns for s and b).
"""

from __future__ import annotations

import numpy as np

from wsnloc.filters.kalman import identity
from wsnloc.filters.measurement_models import RangeModel

EXTRA_STATES = {"none": (), "scale": ("scale",), "offset": ("offset",), "scale_offset": ("scale", "offset")}
MODES = tuple(EXTRA_STATES)


def extra_states(mode: str) -> tuple[str, ...]:
    """Names of the calibration states a mode adds, in state order."""
    return EXTRA_STATES[mode]


def augment_prior(x0: np.ndarray, P0: np.ndarray, mode: str, scale_sigma: float,
                  offset_sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
    """[x0, 1 (scale), 0 (offset)] and blockdiag(P0, scale_sigma^2, offset_sigma_m^2)."""
    names = extra_states(mode)
    start = {"scale": 1.0, "offset": 0.0}
    variance = {"scale": scale_sigma**2, "offset": offset_sigma_m**2}
    n = len(x0)
    x = np.concatenate([x0, [start[k] for k in names]])
    P = np.zeros((n + len(names), n + len(names)))
    P[:n, :n] = P0
    P[n:, n:] = np.diag([variance[k] for k in names])
    return x, P


def augment_motion(F: np.ndarray, Q: np.ndarray, B: np.ndarray | None, extra: int):
    """F, Q, B of the augmented state: identity on the calibration states, no process noise."""
    n = len(F)
    Fa, Qa = identity(n + extra).copy(), np.zeros((n + extra, n + extra))
    Fa[:n, :n], Qa[:n, :n] = F, Q
    Ba = None if B is None else np.vstack([B, np.zeros((extra, B.shape[1]))])
    return Fa, Qa, Ba


def _calibration(X: np.ndarray, mode: str) -> tuple[int, np.ndarray | float, np.ndarray | float]:
    """(n, s, b) of augmented states X (..., n + extra): the motion state's size, the scale
    (1 without one) and the offset (0 without one), each (..., 1) to scale a row of ranges."""
    names = extra_states(mode)
    n = X.shape[-1] - len(names)
    scale = X[..., n + names.index("scale"), None] if "scale" in names else 1.0
    offset = X[..., n + names.index("offset"), None] if "offset" in names else 0.0
    return n, scale, offset


def linearise(model, x: np.ndarray, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """(h(x), H) of a measurement model (filters.measurement_models) at the augmented state x."""
    if mode == "none":
        return model.linearise(x)
    n, scale, offset = _calibration(x, mode)
    names, parts = extra_states(mode), getattr(model, "parts", [model])
    if len(parts) == 1:
        return _augmented_rows(parts[0], x, n, scale, offset, names)
    hs, Hs = zip(*(_augmented_rows(part, x, n, scale, offset, names) for part in parts))
    return np.concatenate(hs), np.vstack(Hs)


def _augmented_rows(part, x: np.ndarray, n: int, scale, offset,
                    names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(h, H) of one model part at the augmented state x (n motion states, then `names`): a range
    part's s d_i + b with the columns s dd_i/dx, d_i (scale), 1 (offset); another part's own h, H
    with zero calibration columns. The part linearised at x itself gives H with a column per state
    entry, zero beyond the position (filters.measurement_models: h reads the position only)."""
    h, H = part.linearise(x)
    if isinstance(part, RangeModel):
        H[:, :n] *= scale
        for k, name in enumerate(names):
            H[:, n + k] = h if name == "scale" else 1.0
        h = scale * h + offset
    return h, H


def h_many(model, X: np.ndarray, mode: str) -> np.ndarray:
    """h at every augmented state of X (N, n + extra): (N, m), the range rows s d_i + b."""
    if mode == "none":
        return model.h_many(X)
    n, scale, offset = _calibration(X, mode)
    return np.hstack([scale * part.h_many(X[:, :n]) + offset if isinstance(part, RangeModel)
                      else part.h_many(X[:, :n]) for part in getattr(model, "parts", [model])])
