"""Range selection and conversion of RSS to distance (paper D)."""

from __future__ import annotations

import numpy as np


def smallest_per_epoch(xy: np.ndarray, distances: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k smallest finite distances of each epoch (all when k = 0 or the epoch has fewer), in increasing
    order with ties in their given order, with their anchors. Paper D keeps only the 6 smallest
    ranges of an epoch: longer ranges are less accurate (exponential path loss, more walls).

    xy (epochs, m, 2), distances (epochs, m) [m], NaN-padded -> (epochs, k', 2), (epochs, k');
    k' = min(k or m, m); an epoch with fewer finite distances is padded with non-finite ones.
    """
    order = np.argsort(np.where(np.isfinite(distances), distances, np.inf), axis=1, kind="stable")[:, :k or None]
    return np.take_along_axis(xy, order[..., None], axis=1), np.take_along_axis(distances, order, axis=1)


def rss_to_distance(rss_dbm, p0_dbm: float, exponent: float, d0_m: float = 1.0) -> np.ndarray:
    """Invert P = P0 - 10 n log10(d / d0):  d = d0 * 10^((P0 - P) / (10 n))  [m]."""
    return d0_m * 10.0 ** ((p0_dbm - np.asarray(rss_dbm, dtype=float)) / (10.0 * exponent))
