"""A path made of straight segments joined by circular arcs (rounded corners).

Used for the Newcom++ rail and the Cricket rectangle. Position along the path is the arc
length s in metres; evaluation gives position, heading and signed curvature, and the height z
where the path has a height profile (a 3-D scenario, Campaign.for_scenario).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class _Line:
    start: np.ndarray
    heading: float
    length: float


@dataclass(frozen=True)
class _Arc:
    center: np.ndarray
    radius: float
    start_angle: float   # polar angle of the arc start seen from the centre (rad)
    turn: float          # +1 left (counter-clockwise), -1 right
    length: float


class Path:
    """Polyline through ``points`` whose interior corners are rounded with ``corner_radius``.

    With corner_radius 0 the corners are sharp (heading jumps, curvature is not defined
    there and is reported as 0). ``heights``: optional (arc length m, height m) points, arc
    lengths increasing; the height between them is linear in the arc length,
    z(s) = h_i + (h_{i+1} - h_i) (s - s_i) / (s_{i+1} - s_i), and constant beyond the ends.
    """

    def __init__(self, points, corner_radius: float = 0.0, heights=None):
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError("path needs at least two (x, y) points")
        self.heights = None if heights is None else np.asarray(heights, dtype=float)
        if self.heights is not None and (self.heights.ndim != 2 or self.heights.shape[1] != 2 or len(self.heights) < 1
                                         or np.any(np.diff(self.heights[:, 0]) <= 0)):
            raise ValueError("height profile needs (arc length, height) points with increasing arc lengths")
        self.points = pts
        self.corner_radius = float(corner_radius)
        self._parts = self._build(pts, self.corner_radius)
        self._starts = np.concatenate([[0.0], np.cumsum([p.length for p in self._parts])])
        self.length = float(self._starts[-1])

    @staticmethod
    def _build(pts: np.ndarray, radius: float) -> list:
        seg = np.diff(pts, axis=0)
        seg_len = np.hypot(seg[:, 0], seg[:, 1])
        if np.any(seg_len <= 0):
            raise ValueError("path has repeated points")
        dirs = seg / seg_len[:, None]
        headings = np.arctan2(dirs[:, 1], dirs[:, 0])
        # Trim distance at each interior corner: r * tan(theta / 2).
        trims = np.zeros(len(pts))
        turns = np.zeros(len(pts))
        for i in range(1, len(pts) - 1):
            a, b = dirs[i - 1], dirs[i]
            turn = np.arctan2(a[0] * b[1] - a[1] * b[0], np.dot(a, b))   # signed turn, left > 0
            turns[i] = turn
            trims[i] = radius * np.tan(abs(turn) / 2.0)
        parts: list = []
        for i in range(len(seg)):
            start = pts[i] + dirs[i] * trims[i]
            length = seg_len[i] - trims[i] - trims[i + 1]
            if length < -1e-9:
                raise ValueError("corner radius too large for the path's segments")
            if length > 1e-12:
                parts.append(_Line(start, float(headings[i]), float(length)))
            corner = i + 1
            if corner < len(pts) - 1 and radius > 0 and abs(turns[corner]) > 1e-12:
                sign = float(np.sign(turns[corner]))
                arc_start = pts[corner] - dirs[i] * trims[corner]
                normal = np.array([-dirs[i][1], dirs[i][0]]) * sign   # towards the centre
                center = arc_start + normal * radius
                start_angle = float(np.arctan2(*(arc_start - center)[::-1]))
                parts.append(_Arc(center, radius, start_angle, sign, radius * abs(turns[corner])))
        return parts

    def evaluate(self, s) -> dict[str, np.ndarray]:
        """Position (m), heading (rad, from +x counter-clockwise) and curvature (1/m, left > 0),
        and height z (m) when the path has a height profile. s is clipped to [0, length].
        """
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        x = np.empty_like(s)
        y = np.empty_like(s)
        heading = np.empty_like(s)
        curvature = np.zeros_like(s)
        index = np.clip(np.searchsorted(self._starts, s, side="right") - 1, 0, len(self._parts) - 1)
        for k, part in enumerate(self._parts):
            mask = index == k
            if not np.any(mask):
                continue
            u = s[mask] - self._starts[k]
            if isinstance(part, _Line):
                x[mask] = part.start[0] + u * np.cos(part.heading)
                y[mask] = part.start[1] + u * np.sin(part.heading)
                heading[mask] = part.heading
            else:
                angle = part.start_angle + part.turn * u / part.radius
                x[mask] = part.center[0] + part.radius * np.cos(angle)
                y[mask] = part.center[1] + part.radius * np.sin(angle)
                heading[mask] = angle + part.turn * np.pi / 2.0
                curvature[mask] = part.turn / part.radius
        heading = np.arctan2(np.sin(heading), np.cos(heading))
        pose = {"x": x, "y": y, "heading": heading, "curvature": curvature}
        if self.heights is not None:
            pose["z"] = np.interp(s, self.heights[:, 0], self.heights[:, 1])
        return pose

    def start_pose(self) -> tuple[float, float, float]:
        """(x, y, heading) at s = 0: the known initial condition for dead reckoning."""
        e = self.evaluate(np.array([0.0]))
        return float(e["x"][0]), float(e["y"][0]), float(e["heading"][0])
