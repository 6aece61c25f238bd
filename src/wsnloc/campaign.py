"""A measurement campaign: floor plan, anchors, path, scenarios and the physical models.

Loaded from ``config/campaigns/<name>.yaml``. Both the simulator and the ingest read the
campaign; the raw run directories hold only what a logger would write.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path as FsPath

import numpy as np
import pandas as pd

from wsnloc.config import parse_yaml, read_yaml, validate
from wsnloc.errors import ConfigError
from wsnloc.geometry.path import Path
from wsnloc.geometry.walls import count_crossings, wall_pieces


def _campaign_schema() -> dict:
    text = resources.files("wsnloc.schemas").joinpath("campaign.schema.yaml").read_text()
    return parse_yaml(text)


@dataclass
class Campaign:
    """Parsed, validated campaign file. ``spec`` keeps the full mapping for model sections."""

    name: str
    format: str
    spec: dict
    source: str = ""
    walls: np.ndarray = field(init=False)
    anchors: pd.DataFrame = field(init=False)
    path: Path | None = field(init=False)

    def __post_init__(self) -> None:
        self.walls = wall_pieces(self.spec.get("walls", []))
        self.anchors = pd.DataFrame(self.spec.get("anchors", []), columns=None if self.spec.get("anchors")
                                    else ["id", "tech", "x", "y"]).rename(columns={"id": "anchor_id"})
        if "z" not in self.anchors:
            self.anchors["z"] = np.nan
        duplicated = self.anchors["anchor_id"][self.anchors["anchor_id"].duplicated()]
        if len(duplicated):
            raise ConfigError(f"{self.source}: key 'anchors': duplicate anchor id {duplicated.iloc[0]!r}")
        known = set(self.anchors["anchor_id"])
        for subset, members in self.spec.get("subsets", {}).items():
            unknown = [m for m in members if m not in known]
            if unknown:
                raise ConfigError(f"{self.source}: key 'subsets.{subset}': unknown anchor {unknown[0]!r}")
        path = self.spec.get("path")
        try:
            self.path = Path(path["points"], path.get("corner_radius_m", 0.0)) if path else None
        except ValueError as exc:
            raise ConfigError(f"{self.source}: key 'path': {exc}") from exc

    @classmethod
    def load(cls, path: str | FsPath) -> "Campaign":
        spec = read_yaml(path)
        validate(spec, _campaign_schema(), source=f"campaign file {path}")
        return cls(name=spec["name"], format=spec["format"], spec=spec, source=str(path))

    def for_scenario(self, scenario: str) -> "Campaign":
        """The campaign as one of its scenarios sees it. A 3-D scenario (keys `tag_height_m`: the
        tag's height profile, [arc length m, height m] points along the path, linear between them;
        `anchor_heights_m`: {anchor id: z m}) gets a path with that height profile (pose z, m) and
        those anchors' z; any other scenario, or a name the campaign does not define, the campaign
        itself. The simulator writes a scenario's logs and the ingest reads them with it."""
        spec = (self.spec.get("scenarios") or {}).get(scenario) or {}
        if "tag_height_m" not in spec and "anchor_heights_m" not in spec:
            return self
        heights = spec.get("anchor_heights_m") or {}
        known = set(self.anchors["anchor_id"])
        unknown = [a for a in heights if a not in known]
        if unknown:
            raise ConfigError(f"{self.source}: key 'scenarios.{scenario}.anchor_heights_m': unknown anchor {unknown[0]!r}")
        anchors = [dict(a, z=float(heights[a["id"]])) if a["id"] in heights else a for a in self.spec["anchors"]]
        out = Campaign(name=self.name, format=self.format, spec=dict(self.spec, anchors=anchors), source=self.source)
        if "tag_height_m" in spec:
            try:
                out.path = Path(self.path.points, self.path.corner_radius, spec["tag_height_m"])
            except ValueError as exc:
                raise ConfigError(f"{self.source}: key 'scenarios.{scenario}.tag_height_m': {exc}") from exc
        return out

    def section(self, *keys: str):
        """Nested model parameters, e.g. ``section('radio', 'uwb')``; names the missing key."""
        node = self.spec
        for depth, key in enumerate(keys):
            if not isinstance(node, dict) or key not in node:
                dotted = ".".join(keys[: depth + 1])
                raise ConfigError(f"{self.source}: key '{dotted}' is required by this campaign's models")
            node = node[key]
        return node

    def anchors_of(self, tech: str) -> pd.DataFrame:
        """Anchors of one technology (e.g. 'uwb', 'zigbee'), in file order."""
        return self.anchors[self.anchors["tech"] == tech].reset_index(drop=True)

    def anchor_position(self, anchor_id: str) -> np.ndarray:
        row = self.anchors.loc[self.anchors["anchor_id"] == anchor_id]
        return row[["x", "y"]].to_numpy(dtype=float)[0]

    @property
    def tag_height_m(self) -> float | None:
        """Antenna height of the mobile (m) when the campaign's ranges are 3-D, else None."""
        return self.spec.get("tag_height_m")

    def walls_between(self, points: np.ndarray, anchor_xy: np.ndarray) -> np.ndarray:
        """Walls crossed by the straight link from each point to the anchor."""
        return count_crossings(points, anchor_xy, self.walls)


@cache
def generic_site() -> Campaign:
    """The site of a run without a campaign file (generic format): no walls, no path, no tag
    height; the anchors come from the run's own table. One shared instance (read, never changed)."""
    return Campaign(name="generic", format="generic", spec={}, source="(no campaign file)")
