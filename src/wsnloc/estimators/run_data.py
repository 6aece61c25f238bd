"""What an estimator reads: one run's canonical tables, its campaign, and the RSS model.

`RunData` is the single input of every estimator in the registry. It answers the
questions all estimators share (where is anchor A, which anchors does a subset name,
which ranges are usable, on which time grid do the run's estimates fall) and caches the
derived products that several estimators of one run reuse (epochs, fixes, dead
reckoning), keyed by the parameters they depend on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError, WsnlocError
from wsnloc.estimators.epochs import grid_over
from wsnloc.io import tables as canonical

ALL_ANCHORS = "all"


def preliminary_filter(ranges: pd.DataFrame, max_range_m: float) -> pd.DataFrame:
    """Paper D's preliminary filter: drop records with a non-zero device status and
    physically impossible values (not finite, <= 0, or longer than max_range_m)."""
    return ranges[~np.any(list(preliminary_filter_reasons(ranges, max_range_m).values()), axis=0)]


def preliminary_filter_reasons(ranges: pd.DataFrame, max_range_m: float) -> dict[str, np.ndarray]:
    """Per reason, the rows (bool) the preliminary filter drops; each row under its first reason."""
    r, valid = ranges["range_m"].to_numpy(float), ranges["status"].to_numpy() == 0
    finite = valid & np.isfinite(r)
    return {"with a device status other than 0": ~valid, "not finite": valid & ~np.isfinite(r),
            "not positive": finite & (r <= 0), "longer than max_range_m": finite & (r > max_range_m)}


@dataclass
class RunData:
    """One run: canonical tables (ranges, rss, truth, anchors; imu and imu_5hz when an
    estimator needs them), the campaign (None for a generic run without a campaign file)
    and the RSS path-loss model and range calibration this run is evaluated with (calibrated
    elsewhere, on donor runs)."""

    tables: dict[str, pd.DataFrame]
    campaign: Campaign | None = None
    rss_model: dict | None = None
    name: str = "run"
    range_model: dict | None = None      # range scale / per-anchor offsets fitted on a donor run
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        anchors = self.table("anchors")
        if len(anchors) == 0 and self.campaign is not None:
            anchors = self.campaign.anchors
        self._xy = {a: (float(x), float(y)) for a, x, y in zip(anchors["anchor_id"], anchors["x"], anchors["y"])}
        tag = self.campaign.tag_height_m if self.campaign is not None else None
        self.tag_height_m = float(tag or 0.0)
        heights = anchors["z"] if "z" in anchors else pd.Series(np.nan, index=anchors.index)
        # 3-D ranges where the anchor has a height: dz = z_anchor - h_tag (h_tag 0 without a campaign value)
        self._dz = {a: (float(z) - self.tag_height_m) if np.isfinite(z) else 0.0
                    for a, z in zip(anchors["anchor_id"], heights.astype(float))}
        self._three_d = any(v != 0.0 for v in self._dz.values())

    def table(self, name: str) -> pd.DataFrame:
        """A canonical table of the run (empty, with its columns, when the run has none)."""
        frame = self.tables.get(name)
        return canonical.empty(name) if frame is None else frame

    def require(self, name: str, why: str) -> pd.DataFrame:
        frame = self.tables.get(name)
        if frame is None or len(frame) == 0:
            raise WsnlocError(f"{self.name}: {why} needs the {name!r} table, which this run does not have")
        return frame

    # ---- anchors -------------------------------------------------------------------------
    def positions(self, ids) -> np.ndarray:
        """(m, 2) anchor coordinates (m) of the anchor ids."""
        return np.array([self._xy[a] for a in ids], dtype=float).reshape(-1, 2)

    def positions_3d(self, ids) -> np.ndarray:
        """(m, 3) anchor coordinates (m); an anchor without a height is at the tag height
        (tag_height_m: the campaign's fixed tag height, 0 without one), as in 2-D."""
        return np.column_stack([self.positions(ids), self.tag_height_m + self.height_offsets(ids)])

    def height_offsets(self, ids) -> np.ndarray:
        """(m,) anchor height minus tag height (m); 0 for 2-D anchors."""
        return np.array([self._dz[a] for a in ids], dtype=float)

    @property
    def three_d(self) -> bool:
        """Whether some anchor is not at the tag height (3-D ranges; read per measurement group)."""
        return self._three_d

    def subset_positions(self, expression: str) -> np.ndarray:
        """(n, 2) positions (m) of the anchors of a subset expression (members), in id order."""
        return self.positions(sorted(self.members(expression)))

    def members(self, expression: str) -> set[str]:
        """Anchor ids of a subset expression: 'all', or campaign subset names joined by '+'
        (their union, e.g. 'UWB=9+ZigBee=17')."""
        if expression == ALL_ANCHORS:
            return set(self._xy)
        subsets = self.campaign.spec.get("subsets", {}) if self.campaign is not None else {}
        out: set[str] = set()
        for name in expression.split("+"):
            if name not in subsets:
                raise ConfigError(f"anchor subset {name!r} (in {expression!r}) is not defined in "
                                  f"{self.campaign.source if self.campaign else 'a campaign file'}"
                                  f" (defined: {', '.join(subsets) or 'none'}; or use 'all')")
            out |= set(subsets[name])
        return out

    # ---- measurements --------------------------------------------------------------------
    def usable_ranges(self, apply_filter: bool, max_range_m: float) -> pd.DataFrame:
        """Ranges to known anchors; with `apply_filter` the preliminary filter, else finite ones."""
        def build():
            ranges = self.table("ranges")
            ranges = ranges[ranges["anchor_id"].isin(self._xy)]
            return preliminary_filter(ranges, max_range_m) if apply_filter else ranges[np.isfinite(ranges["range_m"])]
        return self.cached(("usable_ranges", apply_filter, max_range_m), build)

    def usable_rss(self) -> pd.DataFrame:
        """RSS samples of known anchors with a finite value."""
        def build():
            rss = self.table("rss")
            return rss[rss["anchor_id"].isin(self._xy) & np.isfinite(rss["rss_dbm"])]
        return self.cached(("usable_rss",), build)

    def usable_tdoa(self) -> pd.DataFrame:
        """Range differences (tdoa table) of pairs of two distinct known anchors, finite."""
        def build():
            tdoa = self.table("tdoa")
            return tdoa[tdoa["anchor_id"].isin(self._xy) & tdoa["ref_anchor_id"].isin(self._xy)
                        & (tdoa["anchor_id"] != tdoa["ref_anchor_id"]) & np.isfinite(tdoa["tdoa_m"])]
        return self.cached(("usable_tdoa",), build)

    def grid(self, period: float, apply_filter: bool, max_range_m: float) -> np.ndarray:
        """Epoch end times (s) of the run: every `period` s from its first usable measurement
        (any anchor, ranges, RSS or TDOA) to its last. One grid per run, shared by every estimator
        and anchor subset, so that their outputs fall at the same times and pair up.

        The phase of the grid against periodic ranging rounds matters to estimators that do
        not predict to the output time (Min-Max, multilateration): their fix is as old as
        the round, up to one period at the epoch end."""
        return self.cached(("grid", period, apply_filter, max_range_m),
                           lambda: grid_over(self.measurement_times(apply_filter, max_range_m), period))

    def measurement_times(self, apply_filter: bool, max_range_m: float) -> np.ndarray:
        """The times (s) of every usable measurement (ranges, RSS, TDOA), sorted."""
        return self.cached(("measurement_times", apply_filter, max_range_m), lambda: np.sort(np.concatenate([
            self.usable_ranges(apply_filter, max_range_m)["t"].to_numpy(float), self.usable_rss()["t"].to_numpy(float),
            self.usable_tdoa()["t"].to_numpy(float)])))

    def cached(self, key: tuple, build: Callable):
        """`build()` once per run and key: estimators of one run share epochs, fixes, dead reckoning."""
        if key not in self._cache:
            self._cache[key] = build()
        return self._cache[key]
