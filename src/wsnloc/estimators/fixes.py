"""Per-epoch position fixes: a solver (Min-Max or multilateration) on one technique's
distances, or their fusion (paper D).

Techniques: `toa` (measured ranges, projected to the tag's plane for 3-D anchors), `rss`
(RSS turned into distances by inverting the path-loss model), `pmix` (weighted barycentre
of the toa and rss fixes) and `fmix` (one solver on the toa and rss distances together).
Each solver sees only the k smallest distances of its set (k = 0: all), paper D's
selection: longer ranges are less accurate.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.estimators.measurements import MeasurementSource, rss_params
from wsnloc.estimators.run_data import RunData
from wsnloc.geometry.lateration import LOCALIZERS
from wsnloc.geometry.selection import k_smallest

SOLVERS = tuple(LOCALIZERS)                    # minmax, multilateration
TECHNIQUES = ("toa", "rss", "pmix", "fmix")


def _solve(solver, xy: np.ndarray, distances: np.ndarray, k: int) -> np.ndarray | None:
    keep = k_smallest(distances, k or len(distances))
    fix = solver(xy[keep], distances[keep])
    return fix if fix is not None and np.all(np.isfinite(fix)) else None


def epoch_fixes(data: RunData, p: dict, technique: str) -> pd.DataFrame:
    """(t, x, y) at every epoch of the run grid; x, y NaN where the technique has no fix.

    p: solver, anchors, epoch_s, k_smallest, preliminary_filter, max_range_m, the RSS model
    (measurements.rss_params) and pmix_toa_weight (w; the rss fix gets 1 - w).
    """
    if technique == "pmix":
        return _pmix(epoch_fixes(data, p, "toa"), epoch_fixes(data, p, "rss"), p["pmix_toa_weight"])
    rss = rss_params(data, p) if technique != "toa" else None
    key = ("fixes", technique, p["solver"], p["anchors"], p["epoch_s"], p["k_smallest"], p["preliminary_filter"],
           p["max_range_m"], rss)
    return data.cached(key, lambda: _epoch_fixes(data, p, technique, rss))


def _pmix(toa: pd.DataFrame, rss: pd.DataFrame, w: float) -> pd.DataFrame:
    """P-mix: (w p_toa + (1 - w) p_rss) / (w + (1 - w)) per epoch over the fixes that exist
    (one alone when the other technique has no fix; NaN when neither has)."""
    fixes = np.stack([rss[["x", "y"]].to_numpy(), toa[["x", "y"]].to_numpy()])        # (2, epochs, 2)
    weights = np.where(np.isfinite(fixes[..., 0]), np.array([[1.0 - w], [w]]), 0.0)   # (2, epochs)
    total = weights.sum(axis=0)
    with np.errstate(invalid="ignore"):
        mixed = np.nansum(fixes * weights[..., None], axis=0) / total[:, None]
    mixed[total == 0] = np.nan
    return pd.DataFrame({"t": toa["t"].to_numpy(), "x": mixed[:, 0], "y": mixed[:, 1]})


def _epoch_fixes(data: RunData, p: dict, technique: str, rss) -> pd.DataFrame:
    kinds = {"toa": "toa", "rss": "rss"}.get(technique, "hybrid")
    source = MeasurementSource(data, kinds, p["anchors"], 1.0, p["preliminary_filter"], p["max_range_m"], rss)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    solver, k = LOCALIZERS[p["solver"]], p["k_smallest"]
    empty = np.array([], dtype=object)
    out = np.full((len(times), 2), np.nan)
    for i, e in enumerate(source.epochs(times, p["epoch_s"])):
        toa = source.horizontal_distances(e.range_ids, e.ranges, empty, np.array([])) if technique != "rss" else None
        nb = source.horizontal_distances(empty, np.array([]), e.rss_ids, e.rss) if rss is not None else None
        if technique == "toa":
            fix = _solve(solver, *toa, k)
        elif technique == "rss":
            fix = _solve(solver, *nb, k)
        else:                                                     # fmix
            fix = _solve(solver, np.vstack([nb[0], toa[0]]), np.concatenate([nb[1], toa[1]]), k)
        if fix is not None:
            out[i] = fix
    return pd.DataFrame({"t": times, "x": out[:, 0], "y": out[:, 1]})
