"""The measurements one estimator reads, as epochs or as time-ordered groups, with their
measurement models and the initial fix.

An estimator reads ranges (`toa`), RSS (`rss`) or both (`hybrid`) from the anchors of
its subset. Per epoch (t_k - T, t_k] the ranges to one anchor are averaged (m) and the
RSS samples of one anchor averaged in dB; in sequential use every record is its own
measurement and records that share a time stamp form one group (one update).
Measurement models (filters.measurement_models): TOA ranges, 3-D when anchors have a
height (h = sqrt(d^2 + dz^2)); RSS by the log-distance model P0 - 10 n log10(d / d0).
With a 3-D state (`dimensions` 3) the models take the anchors' (x, y, z) and the tag's height
from the state (h = ||p - a_i||); initiator fixes are then 3-D (lateration.multilateration_3d).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pandas as pd

from wsnloc.estimators.epochs import AnchorMeans, Epoch, anchor_means, per_epoch, sorted_codes
from wsnloc.estimators.range_calibration import RangeCorrection
from wsnloc.estimators.run_data import RunData
from wsnloc.filters.measurement_models import RangeModel, RssModel, Stacked
from wsnloc.geometry.lateration import multilateration, multilateration_3d, weighted_centroid
from wsnloc.geometry.selection import rss_to_distance

KINDS = {"toa": ("ranges",), "rss": ("rss",), "hybrid": ("ranges", "rss"), "tdoa": ("tdoa",)}   # tdoa: estimators.tdoa


@dataclass(frozen=True)
class RssParams:
    """Log-distance path-loss model: P(d) = P0 + o_a - 10 n log10(d / d0) + N(0, sigma^2) [dBm],
    o_a the receiver's P0 offset (dB; `offsets_db` pairs (anchor, o_a), 0 for others: a model
    fitted on a donor, experiments.calibration.donor_rss_model). The models use the common P0
    and the measurements are corrected by their receiver's offset (`correct`)."""

    p0_dbm: float
    path_loss_exponent: float
    sigma_db: float
    d0_m: float = 1.0
    offsets_db: tuple[tuple[str, float], ...] = ()

    @classmethod
    def of(cls, model: dict) -> "RssParams":
        return cls(model["p0_dbm"], model["path_loss_exponent"], model["sigma_db"], model.get("d0_m", 1.0),
                   tuple(sorted((model.get("p0_offsets_db") or {}).items())))

    def correct(self, rss: pd.DataFrame) -> pd.DataFrame:
        """RSS rows with rss_dbm - o_a (dBm): what a receiver with the common P0 would read."""
        if not self.offsets_db:
            return rss
        return rss.assign(rss_dbm=rss["rss_dbm"] - rss["anchor_id"].map(dict(self.offsets_db)).fillna(0.0))


def rss_params(data: RunData, p: dict) -> RssParams:
    """The run's calibrated model (fitted on a donor run, `rss_calibration: other_run` or
    `other_run_common`) when the caller provided one, else the configured p0_dbm,
    path_loss_exponent, sigma_db, d0_m."""
    if p["rss_calibration"] != "configured" and data.rss_model:
        return RssParams.of(data.rss_model)
    return RssParams(p["p0_dbm"], p["path_loss_exponent"], p["sigma_db"], p["d0_m"])


@dataclass
class Coded:
    """One kind of measurement of a run (its usable ranges or RSS) as arrays: t (s), value
    (m or dBm) and the anchor as a code, the index of its id in `ids` (the distinct ids,
    sorted, object). Sources of any anchor subset select their rows from it."""

    t: np.ndarray
    value: np.ndarray
    code: np.ndarray
    ids: np.ndarray

    @classmethod
    def of(cls, frame: pd.DataFrame, value: str) -> "Coded":
        ids, code = sorted_codes(frame["anchor_id"])
        return cls(frame["t"].to_numpy(float), frame[value].to_numpy(float), code, ids.astype(object))

    def among(self, members: set[str]) -> np.ndarray:
        """Per distinct id (code): whether it is one of `members`."""
        return np.array([a in members for a in self.ids], dtype=bool)


class MeasurementSource:
    """Ranges and/or RSS of one anchor subset of a run, filtered as configured; the ranges
    corrected by the range calibration (estimators.range_calibration) when one is given.

    The run's usable ranges and RSS are coded once per run (Coded, shared by every source);
    the per-anchor epoch means are computed once per run and kind over all anchors and
    selected per subset (a mean over one anchor's samples does not depend on the others).
    Epochs, records and initiator fixes are cached per run under the measurement set's key
    (kinds, anchors, filter, correction), so sources that differ only in their noise
    settings share them."""

    def __init__(self, data: RunData, kinds: str, anchors: str, range_sigma_m: float, apply_filter: bool,
                 max_range_m: float, rss: RssParams | None, correction: RangeCorrection = RangeCorrection(),
                 dimensions: int = 2):
        self.data, self.kinds, self.range_sigma_m, self.rss_params = data, KINDS[kinds], range_sigma_m, rss
        self.dimensions = dimensions
        self.correction = correction
        if "rss" in self.kinds and rss is None:
            raise ValueError("RSS measurements need an RSS model")
        self._tables = {"ranges": (("ranges", apply_filter, max_range_m, correction),
                                   lambda: correction.apply(data.usable_ranges(apply_filter, max_range_m)), "range_m"),
                        "rss": (("rss", rss.offsets_db if rss else ()),
                                lambda: rss.correct(data.usable_rss()) if rss else data.usable_rss(), "rss_dbm")}
        self._members = data.members(anchors)
        self._data_key = (kinds, anchors, apply_filter, max_range_m, correction, rss.offsets_db if rss else ())
        self._key = (kinds, anchors, range_sigma_m, apply_filter, max_range_m, rss, correction, dimensions)

    def _coded(self, kind: str) -> Coded:
        """The run's usable measurements of `kind` ("ranges" or "rss"), coded (once per run)."""
        key, frame, value = self._tables[kind]
        return self.data.cached(("coded",) + key, lambda: Coded.of(frame(), value))

    def _rows(self, kind: str) -> np.ndarray:
        """bool per row of _coded(kind): the measurements this source reads."""
        if kind not in self.kinds:
            return np.zeros(len(self._coded(kind).t), dtype=bool)
        coded = self._coded(kind)
        return coded.among(self._members)[coded.code]

    def _frame(self, kind: str) -> pd.DataFrame:
        return self._tables[kind][1]()[self._rows(kind)]

    @cached_property
    def ranges(self) -> pd.DataFrame:
        """The ranges this source reads (rows of the run's usable, corrected ranges)."""
        return self._frame("ranges")

    @cached_property
    def rss(self) -> pd.DataFrame:
        """The RSS samples this source reads (rows of the run's usable RSS)."""
        return self._frame("rss")

    # ---- models ------------------------------------------------------------------------
    def model(self, range_ids, ranges, rss_ids, rss) -> Stacked | None:
        """Stacked range and RSS models with the measured vector z; None when empty."""
        parts, z = [], []
        spatial = self.dimensions == 3
        if len(ranges):
            sigma = np.full(len(ranges), self.range_sigma_m)
            parts.append(RangeModel(self.data.positions_3d(range_ids), sigma) if spatial else
                         RangeModel(self.data.positions(range_ids), sigma,
                                    self.data.height_offsets(range_ids) if self.data.three_d else None))
            z.append(np.asarray(ranges, dtype=float))
        if len(rss):
            p = self.rss_params
            if spatial:
                parts.append(RssModel(self.data.positions_3d(rss_ids), p.p0_dbm, p.path_loss_exponent, p.sigma_db,
                                      p.d0_m))
            else:
                parts.append(RssModel(self.data.positions(rss_ids), p.p0_dbm, p.path_loss_exponent, p.sigma_db,
                                      p.d0_m, self.data.height_offsets(rss_ids) if self.data.three_d else None))
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

    def fix_3d(self, range_ids, ranges, rss_ids, rss) -> np.ndarray | None:
        """(x, y, z) fix (m): 3-D multilateration on the ranges (lateration.multilateration_3d,
        >= 4 anchors not in one plane); where that has none, the 2-D fix at the fixed tag
        height (RunData.tag_height_m); None without either."""
        fix = multilateration_3d(self.data.positions_3d(range_ids), ranges) if len(ranges) else None
        if fix is not None:
            return fix
        flat = self.fix(range_ids, ranges, rss_ids, rss)
        return None if flat is None else np.append(flat, self.data.tag_height_m)

    # ---- epochs ------------------------------------------------------------------------
    def epoch_means(self, times: np.ndarray, period: float) -> tuple[AnchorMeans, AnchorMeans]:
        """(range means (m), RSS means (dB)) per epoch ending at `times` and anchor of this
        source (epochs.anchor_means; codes into _coded(kind).ids)."""
        return tuple(self._epoch_means(kind, times, period) for kind in ("ranges", "rss"))

    def _epoch_means(self, kind: str, times: np.ndarray, period: float) -> AnchorMeans:
        if kind not in self.kinds:
            return AnchorMeans(np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), np.zeros(0))
        coded = self._coded(kind)
        key = ("anchor_means",) + self._tables[kind][0] + (period, times.tobytes())
        means = self.data.cached(key, lambda: anchor_means(coded.t, coded.code, coded.value, times, period))
        return means.select(coded.among(self._members)[means.code])

    def anchor_ids(self, kind: int) -> np.ndarray:
        """The ids (object) the codes of epoch_means(...)[kind] index: 0 ranges, 1 RSS."""
        return self._coded(("ranges", "rss")[kind]).ids

    def epochs(self, times: np.ndarray, period: float) -> list[Epoch]:
        def build():
            ranges, rss = (per_epoch(means, self.anchor_ids(kind), len(times))
                           for kind, means in enumerate(self.epoch_means(times, period)))
            return [Epoch(float(t), gr[0], gr[1], gs[0], gs[1]) for t, gr, gs in zip(times, ranges, rss)]
        return self.data.cached(("epochs", self._data_key, period, len(times)), build)

    def epoch_models(self, times: np.ndarray, period: float) -> list[Stacked | None]:
        """The measurement model of every epoch (shared by the filters of one run)."""
        return self.data.cached(("epoch_models", self._key, period, len(times)), lambda: [
            self.model(e.range_ids, e.ranges, e.rss_ids, e.rss) for e in self.epochs(times, period)])

    # ---- time-ordered records ----------------------------------------------------------
    def records(self) -> "Records":
        return self.data.cached(("records", self._data_key), lambda: Records.of(
            *[(self._coded(kind), self._rows(kind)) for kind in ("ranges", "rss")]))

    @cached_property
    def group_models(self) -> "GroupModels | list[Stacked | None]":
        """The model of every record group (Records.groups), shared by the sequential filters of a run
        that read the same measurements with the same noise: GroupModels on a source with ranges (a
        group of ranges alone built when read, from views of the records' anchor coordinates that
        sources differing only in their noise share: the self-fit's candidates), else a list built
        once."""
        records = self.records()
        if not (records.kind == 0).any():
            return records.models(self.model)
        return GroupModels(self, records, *self._range_geometry())

    def _range_geometry(self) -> tuple[np.ndarray, np.ndarray | None]:
        """Per record of records(): the range model's anchor coordinates (N, 2), or (N, 3) with a 3-D
        state, and height differences dz (N,) (None where `model` passes none: a 3-D state, or no
        anchor off the tag height); NaN on RSS rows. Cached per run and measurement set."""
        def build():
            records = self.records()
            ranges = records.kind == 0
            ids = records.anchor[ranges]
            spatial, three_d = self.dimensions == 3, self.data.three_d
            xy = self.data.positions_3d(ids) if spatial else self.data.positions(ids)
            anchors = np.full((len(records.t), xy.shape[1]), np.nan)
            anchors[ranges] = xy
            if spatial or not three_d:
                return anchors, None
            dz = np.full(len(records.t), np.nan)
            dz[ranges] = self.data.height_offsets(ids)
            return anchors, dz
        return self.data.cached(("range_geometry", self._data_key, self.dimensions), build)

    def window_fix(self, t: float, window: float, axes: int = 2) -> np.ndarray | None:
        """Multilateration (fix, or fix_3d with axes 3) on the per-anchor means of the records in
        (t - window, t] (Records.window_means), on RSS alone the weighted centroid of the receivers
        nearest by the path-loss model (geometry.lateration.weighted_centroid; with axes 3 at the
        fixed tag height); None with fewer than 3 records. Cached per run: sources that share the
        measurement set and RSS model share it."""
        def build():
            records = self.records()
            a, b = np.searchsorted(records.t, [t - window, t], side="right")
            if b - a < 3:
                return None
            means = records.window_means(a, b)
            if len(means[1]) == 0:          # RSS only: the weighted centroid of the 3 nearest receivers
                full = t - window >= records.t[0]      # over a full window: a few samples say little
                fix = weighted_centroid(*self.horizontal_distances(*means)) if full else None
                return fix if fix is None or axes == 2 else np.append(fix, self.data.tag_height_m)
            return self.fix_3d(*means) if axes == 3 else self.fix(*means)
        return self.data.cached(("window_fix", self._data_key, self.rss_params, t, window, axes), build)


class GroupModels(Sequence):
    """The measurement models of a source's record groups (Records.groups), models[g] the g-th's:
    MeasurementSource.model of its records. A group of ranges alone is built when read, from views
    of the records' values and of their anchor coordinates and height differences (per record, NaN
    on RSS rows; MeasurementSource._range_geometry), with the source's range sigma: a few
    microseconds, so none is kept and a pass leaves no object per group behind for the garbage
    collector to scan again and again. A group with RSS is built once, on construction."""

    def __init__(self, source: MeasurementSource, records: "Records", anchors: np.ndarray, dz: np.ndarray | None):
        self.records, self.anchors, self.dz = records, anchors, dz
        self.bounds = records.groups().tolist()
        self.sigma = np.full(len(records.t), source.range_sigma_m)
        rss_before = np.r_[0, np.cumsum(records.kind != 0)][self.bounds]      # RSS records before each group
        self.with_rss = {g: source.model(*records.split(self.bounds[g], self.bounds[g + 1]))
                         for g in np.flatnonzero(np.diff(rss_before) > 0).tolist()}

    def __len__(self) -> int:
        return len(self.bounds) - 1

    def __getitem__(self, g: int) -> Stacked:
        if not 0 <= g < len(self):
            raise IndexError(g)
        if g in self.with_rss:
            return self.with_rss[g]
        a, b = self.bounds[g], self.bounds[g + 1]
        return Stacked([RangeModel(self.anchors[a:b], self.sigma[a:b], None if self.dz is None else self.dz[a:b])],
                       self.records.value[a:b])


@dataclass
class Records:
    """All measurements sorted by time (stable): kind 0 = range (m), 1 = RSS (dBm)."""

    t: np.ndarray
    kind: np.ndarray
    anchor: np.ndarray
    value: np.ndarray

    @classmethod
    def of(cls, ranges: tuple[Coded, np.ndarray], rss: tuple[Coded, np.ndarray]) -> "Records":
        """The (coded measurements, bool rows to take) of the ranges and of the RSS."""
        (r, r_rows), (s, s_rows) = ranges, rss
        t = np.concatenate([r.t[r_rows], s.t[s_rows]])
        kind = np.concatenate([np.zeros(r_rows.sum(), dtype=np.int8), np.ones(s_rows.sum(), dtype=np.int8)])
        anchor = np.concatenate([r.ids[r.code[r_rows]], s.ids[s.code[s_rows]]])
        value = np.concatenate([r.value[r_rows], s.value[s_rows]])
        order = np.argsort(t, kind="stable")
        return cls(t[order], kind[order], anchor[order], value[order])

    def groups(self) -> np.ndarray:
        """Start index of each run of equal time stamps, plus len() at the end."""
        if len(self.t) == 0:
            return np.array([0])
        return np.r_[np.flatnonzero(np.r_[True, self.t[1:] != self.t[:-1]]), len(self.t)]

    def models(self, build) -> list:
        """build(*split(a, b)) of every group of groups(): its measurement model (None: none)."""
        bounds = self.groups().tolist()
        return [build(*self.split(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]

    def split(self, a: int, b: int) -> tuple:
        """(range ids, ranges, RSS ids, RSS) of records a..b-1."""
        k = self.kind[a:b]
        if not k.any():                 # ranges only
            return self.anchor[a:b], self.value[a:b], self.anchor[:0], self.value[:0]
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
