"""Per-epoch position fixes: a solver (Min-Max or multilateration) on one technique's
distances, or their fusion (paper D).

Techniques: `toa` (measured ranges, projected to the tag's plane for 3-D anchors), `rss`
(RSS turned into distances by inverting the path-loss model), `pmix` (weighted barycentre
of the toa and rss fixes) and `fmix` (one solver on the toa and rss distances together).
Each solver sees only the k smallest distances of its set (k = 0: all), paper D's
selection: longer ranges are less accurate. When most epochs hear fewer than 3 anchors (ranges
one anchor at a time) an epoch's fix uses the latest mean of each anchor over the last
auto.FIX_WINDOW_S seconds (auto.fix_window_epochs; synchronous rounds: the epoch alone).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.estimators.auto import fix_window_epochs
from wsnloc.estimators.measurements import MeasurementSource, rss_params
from wsnloc.estimators.run_data import RunData
from wsnloc.geometry.lateration import LOCALIZERS
from wsnloc.geometry.selection import smallest_per_epoch

SOLVERS = tuple(LOCALIZERS)                    # minmax, multilateration
TECHNIQUES = ("toa", "rss", "pmix", "fmix")


def epoch_fixes(data: RunData, p: dict, technique: str) -> pd.DataFrame:
    """(t, x, y) at every epoch of the run grid; x, y NaN where the technique has no fix.

    p: solver (with refine for multilateration), anchors, epoch_s, k_smallest, preliminary_filter,
    max_range_m, the RSS model (measurements.rss_params) and pmix_toa_weight (w; the rss fix gets 1 - w).
    """
    if technique == "pmix":
        build = lambda: _pmix(epoch_fixes(data, p, "toa"), epoch_fixes(data, p, "rss"), p["pmix_toa_weight"])  # noqa: E731
    else:
        build = lambda: _epoch_fixes(data, p, technique, rss_params(data, p) if technique != "toa" else None)  # noqa: E731
    return data.cached(fix_key(data, p, technique), build)


def fix_key(data: RunData, p: dict, technique: str) -> tuple:
    """What epoch_fixes' table depends on (its RunData.cached key; also the key of what is
    computed from it, e.g. trackers' velocity pass)."""
    if technique == "pmix":
        return ("fixes", technique, p["pmix_toa_weight"], fix_key(data, p, "toa"), fix_key(data, p, "rss"))
    rss = rss_params(data, p) if technique != "toa" else None
    return ("fixes", technique, p["solver"], p["anchors"], p["epoch_s"], p["k_smallest"], p["preliminary_filter"],
            p["max_range_m"], rss, tuple(solver_options(p).items()))


def solver_options(p: dict) -> dict:
    """Keyword options of the solver: multilateration's `refine` (Gauss-Newton after the linear
    least squares); Min-Max has none."""
    return {"refine": p["refine"]} if p["solver"] == "multilateration" else {}


def _pmix(toa: pd.DataFrame, rss: pd.DataFrame, w: float) -> pd.DataFrame:
    """P-mix: (w p_toa + (1 - w) p_rss) / (w + (1 - w)) per epoch over the fixes that exist
    (one alone when the other technique has no fix; NaN when neither has)."""
    fixes = np.stack([np.column_stack([f["x"].to_numpy(), f["y"].to_numpy()]) for f in (rss, toa)])   # (2, epochs, 2)
    weights = np.where(np.isfinite(fixes[..., 0]), np.array([[1.0 - w], [w]]), 0.0)   # (2, epochs)
    total = weights.sum(axis=0)
    with np.errstate(invalid="ignore"):
        mixed = np.nansum(fixes * weights[..., None], axis=0) / total[:, None]
    mixed[total == 0] = np.nan
    return pd.DataFrame({"t": toa["t"].to_numpy(), "x": mixed[:, 0], "y": mixed[:, 1]})


def _padded(epoch: np.ndarray, xy: np.ndarray, distances: np.ndarray, epochs: int):
    """Measurements (n,) tagged with their epoch index (ascending) as (epochs, m, 2) anchors
    and (epochs, m) distances [m], NaN-padded; each epoch keeps its measurements' order."""
    counts = np.bincount(epoch, minlength=epochs)
    slot = np.arange(len(epoch)) - np.repeat(np.cumsum(counts) - counts, counts)
    width = int(counts.max(initial=0))
    padded_xy, padded = np.full((epochs, width, 2), np.nan), np.full((epochs, width), np.nan)
    padded_xy[epoch, slot], padded[epoch, slot] = xy, distances
    return padded_xy, padded


def _flat(source: MeasurementSource, times: np.ndarray, period: float, kind: int):
    """(epoch index, anchor ids (object), per-anchor epoch means) of one measurement kind
    (0 ranges, 1 RSS) over all epochs, by epoch, then anchor id (MeasurementSource.epochs' order)."""
    means = source.epoch_means(times, period)[kind]
    epoch, ids, values = means.epoch, source.anchor_ids(kind)[means.code], means.mean
    window = fix_window_epochs(np.bincount(epoch, minlength=len(times)), period)
    return _latest_within(epoch, ids, values, len(times), window) if window > 1 else (epoch, ids, values)


def _latest_within(epoch: np.ndarray, ids: np.ndarray, values: np.ndarray, n_epochs: int, window: int):
    """(epoch, anchor ids, values) with each anchor's latest value of the last `window` epochs
    at every epoch (by epoch, then anchor id)."""
    names, column = np.unique(ids.astype(str), return_inverse=True)
    latest = np.full((n_epochs, len(names)), np.nan)
    latest[epoch, column] = values
    latest = pd.DataFrame(latest).ffill(limit=window - 1).to_numpy()
    rows, cols = np.nonzero(np.isfinite(latest))
    return rows, names[cols].astype(object), latest[rows, cols]


def _epoch_fixes(data: RunData, p: dict, technique: str, rss) -> pd.DataFrame:
    """All epochs solved at once: per epoch the toa and/or rss distances (fmix: rss first,
    then toa), their k smallest, the batched solver (geometry.lateration)."""
    kinds = {"toa": "toa", "rss": "rss"}.get(technique, "hybrid")
    source = MeasurementSource(data, kinds, p["anchors"], 1.0, p["preliminary_filter"], p["max_range_m"], rss)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    empty = np.array([], dtype=object)
    parts = []
    if technique != "toa":
        index, ids, values = _flat(source, times, p["epoch_s"], 1)
        parts.append((index, *source.horizontal_distances(empty, np.array([]), ids, values)))
    if technique != "rss":
        index, ids, values = _flat(source, times, p["epoch_s"], 0)
        parts.append((index, *source.horizontal_distances(ids, values, empty, np.array([]))))
    index, xy, distances = (np.concatenate(column) for column in zip(*parts))
    order = np.argsort(index, kind="stable")
    padded = _padded(index[order], xy[order], distances[order], len(times))
    out = LOCALIZERS[p["solver"]](*smallest_per_epoch(*padded, p["k_smallest"]), **solver_options(p))
    out[~np.all(np.isfinite(out), axis=1)] = np.nan
    return pd.DataFrame({"t": times, "x": out[:, 0], "y": out[:, 1]})
