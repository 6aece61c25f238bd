"""Velocity-bounded tracker of paper D (Kianoush et al. 2012, Sec. 3.3).

For each new raw fix p_i at time T_i:
  v_hat = sum_j ||P_{j+1} - P_j|| / sum_j (t_{j+1} - t_j)  over the window of the last N
          positions (eq. 1/6);
  R_b   = v_hat * (T_i - T_{i-1});
  l     = ||p_i - x_{i-1}|| with x_{i-1} the previous tracked position;
  x_i   = p_i if l < R_b, else x_{i-1} + R_b (p_i - x_{i-1}) / l   (on the circle, in the
          direction of the raw fix; eqs. 3-5);
  stop rule: if the raw fix has not changed (p_i == p_{i-1}) the last coordinates are kept.

Which positions feed the speed window: the paper's wording ("the latest N estimated
target positions") can be read as the tracker's own outputs or the raw fixes. With its
own outputs the speed can never increase (each output step is at most R_b), so after any
static phase the tracker freezes for good; with raw fixes the speed estimate is an FIR
average that follows accelerations with a lag and decelerations at once, which is the
behaviour the paper describes. Default `speed_from="raw"`; "tracked" is offered.
Until the window holds two positions the raw fix is accepted.
"""

from __future__ import annotations

import math
from collections import deque
from itertools import islice

import numpy as np


class VelocityBoundedTracker:
    """State: the last N + 1 (time, position) pairs of the speed window, the tracked
    position x_{i-1}, the last raw fix p_{i-1} and its time T_{i-1}; all plain floats (m, s),
    as numpy's per-call overhead on 2-vectors is many times the arithmetic of one step."""

    def __init__(self, window: int = 6, speed_from: str = "raw"):
        if window < 1:
            raise ValueError("tracker window must be at least 1")
        if speed_from not in ("raw", "tracked"):
            raise ValueError(f"speed_from must be 'raw' or 'tracked', not {speed_from!r}")
        self.window = window
        self.speed_from = speed_from
        self._times: deque = deque(maxlen=window + 1)      # N steps need N + 1 positions
        self._points: deque = deque(maxlen=window + 1)
        self.position: tuple[float, float] | None = None
        self._last_raw: tuple[float, float] | None = None
        self._last_time: float | None = None
        self.speed = float("nan")

    def _speed(self) -> float:
        """v_hat (m/s): path length over the window / its duration (eq. 1/6); NaN until the
        window holds two positions or if its duration is not positive."""
        if len(self._times) < 2:
            return float("nan")
        elapsed = self._times[-1] - self._times[0]
        if elapsed <= 0:
            return float("nan")
        path = 0.0
        for a, b in zip(self._points, islice(self._points, 1, None)):    # in order (sum() compensates on 3.12+)
            path += math.hypot(b[0] - a[0], b[1] - a[1])
        return path / elapsed

    def update(self, t: float, x: float, y: float) -> tuple[float, float]:
        """Tracked position (x, y) (m) for the raw fix (x, y) (m) at time t (s)."""
        if self.position is None:
            out = (x, y)
        elif x == self._last_raw[0] and y == self._last_raw[1]:
            out = self.position                               # target stopped
        else:
            self.speed = self._speed()
            out = (x, y)
            if math.isfinite(self.speed):
                bound = self.speed * (t - self._last_time)
                px, py = self.position
                dx, dy = x - px, y - py
                length = math.hypot(dx, dy)
                if length >= bound:                          # onto the circle of radius R_b
                    out = (px + bound / length * dx, py + bound / length * dy) if length > 0 else self.position
        self._times.append(t)
        self._points.append((x, y) if self.speed_from == "raw" else out)
        self.position, self._last_raw, self._last_time = out, (x, y), t
        return out

    def step(self, t: float, raw) -> np.ndarray:
        """Tracked position (m) as an array for the raw fix `raw` (x, y; m) at time t (s)."""
        x, y = np.asarray(raw, dtype=float)
        return np.array(self.update(float(t), float(x), float(y)))
