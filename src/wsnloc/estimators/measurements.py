"""The measurements one estimator reads, as epochs or as time-ordered groups, with their
measurement models and the initial fix.

An estimator reads ranges (`toa`), RSS (`rss`) or both (`hybrid`) from the anchors of
its subset. Per epoch (t_k - T, t_k] the ranges to one anchor are averaged (m) and the
RSS samples of one anchor averaged in dB; in sequential use every record is its own
measurement and records that share a time stamp form one group (one update).
Measurement models (filters.measurement_models): TOA ranges, 3-D when anchors have a
height (h = sqrt(d^2 + dz^2)); RSS by the log-distance model P0 - 10 n log10(d / d0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc.estimators.epochs import Epoch, build_epochs
from wsnloc.estimators.range_calibration import RangeCorrection
from wsnloc.estimators.run_data import RunData
from wsnloc.filters.measurement_models import RangeModel, RssModel, Stacked
from wsnloc.geometry.lateration import multilateration
from wsnloc.geometry.selection import rss_to_distance

KINDS = {"toa": ("ranges",), "rss": ("rss",), "hybrid": ("ranges", "rss")}


@dataclass(frozen=True)
class RssParams:
    """Log-distance path-loss model: P(d) = P0 - 10 n log10(d / d0) + N(0, sigma^2) [dBm]."""

    p0_dbm: float
    path_loss_exponent: float
    sigma_db: float
    d0_m: float = 1.0

    @classmethod
    def of(cls, model: dict) -> "RssParams":
        return cls(model["p0_dbm"], model["path_loss_exponent"], model["sigma_db"], model.get("d0_m", 1.0))


def rss_params(data: RunData, p: dict) -> RssParams:
    """The run's calibrated model (fitted on a donor run, `rss_calibration: other_run`) when
    the caller provided one, else the configured p0_dbm, path_loss_exponent, sigma_db, d0_m."""
    if p["rss_calibration"] == "other_run" and data.rss_model:
        return RssParams.of(data.rss_model)
    return RssParams(p["p0_dbm"], p["path_loss_exponent"], p["sigma_db"], p["d0_m"])


class MeasurementSource:
    """Ranges and/or RSS of one anchor subset of a run, filtered as configured; the ranges
    corrected by the range calibration (estimators.range_calibration) when one is given."""

    def __init__(self, data: RunData, kinds: str, anchors: str, range_sigma_m: float, apply_filter: bool,
                 max_range_m: float, rss: RssParams | None, correction: RangeCorrection = RangeCorrection()):
        self.data, self.kinds, self.range_sigma_m, self.rss_params = data, KINDS[kinds], range_sigma_m, rss
        self.correction = correction
        members = data.members(anchors)
        ranges = correction.apply(data.usable_ranges(apply_filter, max_range_m))
        rss_frame = data.usable_rss()
        self.ranges = ranges[ranges["anchor_id"].isin(members)] if "ranges" in self.kinds else ranges.iloc[:0]
        self.rss = rss_frame[rss_frame["anchor_id"].isin(members)] if "rss" in self.kinds else rss_frame.iloc[:0]
        if "rss" in self.kinds and rss is None:
            raise ValueError("RSS measurements need an RSS model")
        self._key = (kinds, anchors, range_sigma_m, apply_filter, max_range_m, rss, correction)

    # ---- models ------------------------------------------------------------------------
    def model(self, range_ids, ranges, rss_ids, rss) -> Stacked | None:
        """Stacked range and RSS models with the measured vector z; None when empty."""
        parts, z = [], []
        if len(ranges):
            parts.append(RangeModel(self.data.positions(range_ids), np.full(len(ranges), self.range_sigma_m),
                                    self.data.height_offsets(range_ids) if self.data.three_d else None))
            z.append(np.asarray(ranges, dtype=float))
        if len(rss):
            p = self.rss_params
            parts.append(RssModel(self.data.positions(rss_ids), p.p0_dbm, p.path_loss_exponent, p.sigma_db, p.d0_m))
            z.append(np.asarray(rss, dtype=float))
        return Stacked(parts, np.concatenate(z)) if parts else None

    def horizontal_distances(self, range_ids, ranges, rss_ids, rss) -> tuple[np.ndarray, np.ndarray]:
        """(anchors (m, 2), horizontal distances (m,)) for lateration: ranges projected to the
        tag's plane (sqrt(r^2 - dz^2)) and RSS inverted to distance by the path-loss model."""
        r = np.asarray(ranges, dtype=float)
        dz = self.data.height_offsets(range_ids)
        horizontal = np.sqrt(np.maximum(r**2 - dz**2, 0.0))
        xy = self.data.positions(range_ids)
        if len(rss):
            p = self.rss_params
            horizontal = np.concatenate([horizontal, rss_to_distance(rss, p.p0_dbm, p.path_loss_exponent, p.d0_m)])
            xy = np.vstack([xy, self.data.positions(rss_ids)])
        return xy, horizontal

    def fix(self, range_ids, ranges, rss_ids, rss) -> np.ndarray | None:
        """Multilateration fix (m) from the given measurements, None with < 3 or collinear anchors."""
        return multilateration(*self.horizontal_distances(range_ids, ranges, rss_ids, rss))

    # ---- epochs ------------------------------------------------------------------------
    def epochs(self, times: np.ndarray, period: float) -> list[Epoch]:
        return self.data.cached(("epochs", self._key, period, len(times)),
                                lambda: build_epochs(self.ranges, self.rss, period, times))

    def epoch_models(self, times: np.ndarray, period: float) -> list[Stacked | None]:
        """The measurement model of every epoch (shared by the filters of one run)."""
        return self.data.cached(("epoch_models", self._key, period, len(times)), lambda: [
            self.model(e.range_ids, e.ranges, e.rss_ids, e.rss) for e in self.epochs(times, period)])

    # ---- time-ordered records ----------------------------------------------------------
    def records(self) -> "Records":
        return self.data.cached(("records", self._key), lambda: Records.of(self.ranges, self.rss))


@dataclass
class Records:
    """All measurements sorted by time (stable): kind 0 = range (m), 1 = RSS (dBm)."""

    t: np.ndarray
    kind: np.ndarray
    anchor: np.ndarray
    value: np.ndarray

    @classmethod
    def of(cls, ranges: pd.DataFrame, rss: pd.DataFrame) -> "Records":
        t = np.concatenate([ranges["t"].to_numpy(float), rss["t"].to_numpy(float)])
        kind = np.concatenate([np.zeros(len(ranges), dtype=np.int8), np.ones(len(rss), dtype=np.int8)])
        anchor = np.concatenate([ranges["anchor_id"].to_numpy(object), rss["anchor_id"].to_numpy(object)])
        value = np.concatenate([ranges["range_m"].to_numpy(float), rss["rss_dbm"].to_numpy(float)])
        order = np.argsort(t, kind="stable")
        return cls(t[order], kind[order], anchor[order], value[order])

    def groups(self) -> np.ndarray:
        """Start index of each run of equal time stamps, plus len() at the end."""
        if len(self.t) == 0:
            return np.array([0])
        return np.r_[np.flatnonzero(np.r_[True, self.t[1:] != self.t[:-1]]), len(self.t)]

    def split(self, a: int, b: int) -> tuple:
        """(range ids, ranges, RSS ids, RSS) of records a..b-1."""
        k = self.kind[a:b]
        return self.anchor[a:b][k == 0], self.value[a:b][k == 0], self.anchor[a:b][k == 1], self.value[a:b][k == 1]

    def window_means(self, a: int, b: int) -> tuple:
        """Like split, with the values of each anchor averaged (ranges in m, RSS in dB)."""
        out = []
        for kind in (0, 1):
            sel = self.kind[a:b] == kind
            ids, values = self.anchor[a:b][sel], self.value[a:b][sel]
            if len(ids) == 0:
                out += [ids, values]
                continue
            unique, inverse = np.unique(ids.astype(str), return_inverse=True)
            out += [unique.astype(object), np.bincount(inverse, weights=values) / np.bincount(inverse)]
        return tuple(out)
