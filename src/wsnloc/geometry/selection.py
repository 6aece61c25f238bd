"""Range selection and conversion of RSS to distance (paper D)."""

from __future__ import annotations

import numpy as np


def k_smallest(ranges, k: int) -> np.ndarray:
    """Indices of the k smallest finite ranges (all of them when fewer), in increasing order.

    Paper D keeps only the 6 smallest ranges of an epoch: longer ranges are less accurate
    (exponential path loss, more walls).
    """
    r = np.asarray(ranges, dtype=float)
    finite = np.flatnonzero(np.isfinite(r))
    order = finite[np.argsort(r[finite], kind="stable")]
    return order[:k]


def rss_to_distance(rss_dbm, p0_dbm: float, exponent: float, d0_m: float = 1.0) -> np.ndarray:
    """Invert P = P0 - 10 n log10(d / d0):  d = d0 * 10^((P0 - P) / (10 n))  [m]."""
    return d0_m * 10.0 ** ((p0_dbm - np.asarray(rss_dbm, dtype=float)) / (10.0 * exponent))
