"""TDOA measurements of one anchor subset as the Bayesian filters read them (`measurements: tdoa`).

A row of the run's `tdoa` table is one range difference d(anchor) - d(ref) (m) of one pair
of anchors at time t. Records sharing a time stamp are one measurement vector (one update,
the sequential mode's time group), with the correlated noise of pairs sharing a receiver
(filters.measurement_models.TdoaModel: R = D diag(sigma^2) D^T, sigma = `range_sigma_m`, the
noise of each anchor's arrival or range). A pair whose difference follows from the others of
the same vector (it closes a cycle, e.g. A-C beside A-B and B-C) would make R singular; it is
left out of that update (under the per-arrival noise model it carries no new information).
In epoch mode each pair's differences within (t_k - T, t_k] are averaged.
The initiator's fix is the hyperbolic solver (geometry.hyperbolic: Chan's closed form and
Gauss-Newton) on the per-pair means of the initiator window.

`TdoaSource` offers the interface the filter loops use of a measurement source
(estimators.core, bayes): records(), model(*records.split(a, b)), group_models (cached), window_fix(t, window),
epoch_models(times, period) and `correction`, the range calibration (range_calibration:
scale and per-anchor offsets, donor-fitted or configured) applied to the differences.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import pandas as pd

from wsnloc.estimators.epochs import anchor_means, per_epoch, sorted_codes
from wsnloc.estimators.measurements import Records
from wsnloc.estimators.range_calibration import RangeCorrection
from wsnloc.estimators.run_data import RunData
from wsnloc.filters.measurement_models import Stacked, TdoaModel
from wsnloc.geometry.hyperbolic import tdoa_fix

PAIR = "\x1f"          # joins anchor and reference ids into one pair key (a control character no id contains)


def independent_pairs(pairs: np.ndarray) -> np.ndarray:
    """bool (m,): the pairs kept, in order, skipping each pair whose two receivers are already
    linked by the kept ones (union-find: the kept pairs form a forest, so D has full row rank)."""
    parent: dict = {}

    def root(j):
        while parent.setdefault(j, j) != j:
            parent[j] = parent[parent[j]]
            j = parent[j]
        return j

    keep = np.zeros(len(pairs), dtype=bool)
    for i, (a, b) in enumerate(pairs):
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[ra] = rb
            keep[i] = True
    return keep


def model_of(data: RunData, anchor_ids, ref_ids, values, sigma_m: float, dimensions: int = 2) -> Stacked | None:
    """TdoaModel of the pairs (anchor_ids[i], ref_ids[i]) with measured differences `values` (m),
    redundant pairs left out (independent_pairs); None without a pair. dimensions 3: the
    receivers' (x, y, z) for a 3-D state (RunData.positions_3d)."""
    if len(values) == 0:
        return None
    receivers, index = np.unique(np.concatenate([np.asarray(anchor_ids, dtype=str), np.asarray(ref_ids, dtype=str)]),
                                 return_inverse=True)
    pairs = index.reshape(2, -1).T
    keep = independent_pairs(pairs)
    if dimensions == 3:
        model = TdoaModel(data.positions_3d(receivers), pairs[keep], sigma_m)
    else:
        dz = data.height_offsets(receivers) if data.three_d else None
        model = TdoaModel(data.positions(receivers), pairs[keep], sigma_m, dz)
    return Stacked([model], np.asarray(values, dtype=float)[keep])


def corrected(frame: pd.DataFrame, correction: RangeCorrection) -> np.ndarray:
    """The range differences (m) of the rows (anchor_id, ref_anchor_id, tdoa_m) under a range
    calibration r = s d + b + b_a (range_calibration): d_a - d_ref = (tdoa - (b_a - b_ref)) / s;
    the common offset b cancels, the pair bias is the difference of the anchors' offsets."""
    offsets = dict(correction.offsets_m)
    bias = (frame["anchor_id"].map(offsets).fillna(0.0).to_numpy(float)
            - frame["ref_anchor_id"].map(offsets).fillna(0.0).to_numpy(float))
    return (frame["tdoa_m"].to_numpy(float) - bias) / correction.scale


class TdoaSource:
    """The range differences of the pairs whose two anchors are in the subset `anchors`."""

    def __init__(self, data: RunData, anchors: str, sigma_m: float, max_range_m: float,
                 correction: RangeCorrection = RangeCorrection(), dimensions: int = 2):
        self.data, self.sigma_m, self.max_range_m = data, sigma_m, max_range_m
        self.correction, self.dimensions = correction, dimensions
        members = data.members(anchors)
        frame = data.usable_tdoa()
        frame = frame[frame["anchor_id"].isin(members) & frame["ref_anchor_id"].isin(members)]
        keys = (frame["anchor_id"] + PAIR + frame["ref_anchor_id"]).to_numpy(dtype=object)
        self._key = ("tdoa", anchors, dimensions, correction)     # the records are corrected: cached fixes too
        self._records = Records(frame["t"].to_numpy(float), np.zeros(len(frame), dtype=np.int8), keys,
                                corrected(frame, correction))

    # ---- models ------------------------------------------------------------------------
    def model(self, keys, values, *_rss) -> Stacked | None:
        """The TdoaModel of the pairs named by their keys, with the measured vector z (m)."""
        if len(values) == 0:
            return None
        return self._model(keys, values, self.dimensions)

    def _model(self, keys, values, dimensions: int) -> Stacked | None:
        anchor_ids, ref_ids = zip(*(str(k).split(PAIR) for k in keys))
        return model_of(self.data, anchor_ids, ref_ids, values, self.sigma_m, dimensions)

    def fix(self, keys, values, *_rss) -> np.ndarray | None:
        """Hyperbolic fix (m) from the given pairs (in the plane, with the tag height's range
        differences); None with fewer than 2 independent pairs."""
        model = self._model(keys, values, 2) if len(values) else None
        return None if model is None else tdoa_fix(model.parts[0], model.z, self.max_range_m)

    # ---- time-ordered records ----------------------------------------------------------
    def records(self) -> Records:
        return self._records

    @cached_property
    def group_models(self) -> list[Stacked | None]:
        """The model of every record group (Records.groups), built once per source."""
        return self._records.models(self.model)

    def window_fix(self, t: float, window: float, axes: int = 2) -> np.ndarray | None:
        """Hyperbolic fix on the per-pair means of the records in (t - window, t]; None with
        fewer than 2 pairs. axes 3: the fix at the fixed tag height (RunData.tag_height_m),
        where a 3-D state starts."""
        def build():
            a, b = np.searchsorted(self._records.t, [t - window, t], side="right")
            return None if b - a < 2 else self.fix(*self._records.window_means(a, b)[:2])
        fix = self.data.cached(("tdoa_window_fix",) + self._key + (self.sigma_m, self.max_range_m, t, window), build)
        return fix if fix is None or axes == 2 else np.append(fix, self.data.tag_height_m)

    # ---- epochs ------------------------------------------------------------------------
    def epoch_models(self, times: np.ndarray, period: float) -> list[Stacked | None]:
        """Per epoch (t_k - T, t_k]: the model of the per-pair means (None without a pair)."""
        def build():
            ids, code = sorted_codes(pd.Series(self._records.anchor, dtype=object))
            means = anchor_means(self._records.t, code, self._records.value, times, period)
            return [self.model(keys, values) for keys, values in per_epoch(means, ids.astype(object), len(times))]
        return self.data.cached(("tdoa_epoch_models",) + self._key + (self.sigma_m, period, times.tobytes()), build)
