"""Walls as 2-D segments with door gaps, and counting the walls a straight link crosses.

A radio link between a mobile at p and an anchor at a is NLOS when the open segment
p-a properly intersects at least one wall piece.
"""

from __future__ import annotations

import numpy as np


def wall_pieces(walls: list[dict]) -> np.ndarray:
    """Split each wall at its doors into solid pieces.

    Each wall is ``{"from": [x, y], "to": [x, y], "doors": [[d0, d1], ...]}`` with door
    intervals given as distances (m) along the wall from its ``from`` end.
    Returns an (M, 4) array of pieces ``[x1, y1, x2, y2]`` in metres.
    """
    pieces: list[list[float]] = []
    for wall in walls:
        start = np.asarray(wall["from"], dtype=float)
        end = np.asarray(wall["to"], dtype=float)
        length = float(np.hypot(*(end - start)))
        direction = (end - start) / length
        cursor = 0.0
        for d0, d1 in sorted(wall.get("doors", [])):
            if d0 > cursor:
                pieces.append([*(start + cursor * direction), *(start + d0 * direction)])
            cursor = max(cursor, d1)
        if cursor < length:
            pieces.append([*(start + cursor * direction), *end])
    return np.asarray(pieces, dtype=float).reshape(-1, 4)


def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


def count_crossings(points: np.ndarray, anchor: np.ndarray, pieces: np.ndarray) -> np.ndarray:
    """Number of wall pieces properly crossed by each segment points[k] -> anchor.

    points: (N, 2) positions in m; anchor: (2,) position in m; pieces: (M, 4).
    A crossing is counted when the two open segments intersect at a single interior
    point (orientation test: the end points of each segment lie strictly on opposite
    sides of the other); grazing contact at an end point does not count.
    Returns an (N,) integer array.
    """
    points = np.atleast_2d(np.asarray(points, dtype=float))
    if pieces.size == 0:
        return np.zeros(len(points), dtype=int)
    px, py = points[:, 0:1], points[:, 1:2]            # (N, 1)
    ax, ay = float(anchor[0]), float(anchor[1])
    w1x, w1y, w2x, w2y = (pieces[:, i][None, :] for i in range(4))  # (1, M)
    # Sides of the wall end points with respect to the link p -> a.
    lx, ly = ax - px, ay - py
    s1 = _cross(lx, ly, w1x - px, w1y - py)
    s2 = _cross(lx, ly, w2x - px, w2y - py)
    # Sides of the link end points with respect to the wall w1 -> w2.
    wx, wy = w2x - w1x, w2y - w1y
    s3 = _cross(wx, wy, px - w1x, py - w1y)
    s4 = _cross(wx, wy, ax - w1x, ay - w1y)
    crosses = (s1 * s2 < 0) & (s3 * s4 < 0)
    return crosses.sum(axis=1)
