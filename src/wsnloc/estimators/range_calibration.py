"""Range calibration applied before the filters: measured r = s d + b + b_a (m), with a common
scale s, a common offset b and per-anchor offsets b_a, corrected as d = (r - b - b_a) / s.

Sources (parameter `range_calibration`):
- `other_run`: s and b_a fitted on a donor run with truth of the same dataset
  (experiments.calibration.calibrate_ranges; the caller puts it in RunData.range_model);
  without a donor the configured values are used, and `source` says so;
- `configured`: the campaign file's `range_calibration: {scale, offset_m, offsets_m: {anchor: m}}`
  (identity when the campaign has none);
- `none`: ranges as measured.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc.errors import ConfigError

SOURCES = ("none", "other_run", "configured")


@dataclass(frozen=True)
class RangeCorrection:
    scale: float = 1.0
    offset_m: float = 0.0
    offsets_m: tuple[tuple[str, float], ...] = ()      # (anchor id, offset in m)
    source: str = "none"

    @classmethod
    def of(cls, model: dict, source: str) -> "RangeCorrection":
        offsets = tuple(sorted((str(a), float(b)) for a, b in (model.get("offsets_m") or {}).items()))
        return cls(float(model.get("scale", 1.0)), float(model.get("offset_m", 0.0)), offsets, source)

    def apply(self, ranges: pd.DataFrame) -> pd.DataFrame:
        """The ranges with range_m corrected: (r - offset_m - offsets_m[anchor]) / scale."""
        if self.scale == 1.0 and self.offset_m == 0.0 and not self.offsets_m:
            return ranges
        per_anchor = ranges["anchor_id"].map(dict(self.offsets_m)).fillna(0.0).to_numpy(float)
        out = ranges.copy()
        out["range_m"] = (ranges["range_m"].to_numpy(float) - self.offset_m - per_anchor) / self.scale
        return out

    def describe(self) -> dict:
        return {"range_calibration": self.source, "calibrated_scale": self.scale,
                "calibrated_offset_m": self.offset_m, "calibrated_offsets_m": dict(self.offsets_m)}


def configured(campaign) -> RangeCorrection:
    """The campaign file's `range_calibration` (identity without one); unknown anchors are refused."""
    spec = (campaign.spec.get("range_calibration") if campaign is not None else None) or {}
    if not spec:
        return RangeCorrection(source="configured (none in the campaign file)")
    known = set(campaign.anchors["anchor_id"])
    for anchor in spec.get("offsets_m") or {}:
        if anchor not in known:
            raise ConfigError(f"{campaign.source}: key 'range_calibration.offsets_m.{anchor}': not an anchor of "
                              f"the campaign")
    return RangeCorrection.of(spec, f"configured in {campaign.source}")


def model_key(model: dict | None):
    """A hashable key of a range model (RunData.range_model: scale, offsets, source, any other
    entries), equal for equal models: mappings as sorted items, recursively; None for none."""
    if isinstance(model, dict):
        return tuple(sorted((str(k), model_key(v)) for k, v in model.items()))
    if isinstance(model, (list, tuple, np.ndarray)):
        return tuple(model_key(v) for v in model)
    return model


def correction(data, p: dict) -> RangeCorrection:
    """The correction a filter with parameters p applies to the ranges of run `data` (RunData)."""
    if p["range_calibration"] == "other_run" and data.range_model:
        return RangeCorrection.of(data.range_model, data.range_model.get("source", "fitted on a donor run"))
    if p["range_calibration"] == "none":
        return RangeCorrection()
    fallback = configured(data.campaign)
    if p["range_calibration"] == "other_run":
        return RangeCorrection(fallback.scale, fallback.offset_m, fallback.offsets_m,
                               f"no donor run of the same dataset: {fallback.source}")
    return fallback
