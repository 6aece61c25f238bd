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

from collections import deque

import numpy as np


class VelocityBoundedTracker:
    def __init__(self, window: int = 6, speed_from: str = "raw"):
        if window < 1:
            raise ValueError("tracker window must be at least 1")
        if speed_from not in ("raw", "tracked"):
            raise ValueError(f"speed_from must be 'raw' or 'tracked', not {speed_from!r}")
        self.window = window
        self.speed_from = speed_from
        self._history: deque = deque(maxlen=window + 1)   # N steps need N + 1 positions
        self.position: np.ndarray | None = None
        self._last_raw: np.ndarray | None = None
        self._last_time: float | None = None
        self.speed = float("nan")

    def _speed(self) -> float:
        if len(self._history) < 2:
            return float("nan")
        times = np.array([t for t, _ in self._history])
        points = np.array([p for _, p in self._history])
        elapsed = times[-1] - times[0]
        if elapsed <= 0:
            return float("nan")
        return float(np.sum(np.hypot(*np.diff(points, axis=0).T)) / elapsed)

    def step(self, t: float, raw) -> np.ndarray:
        """Tracked position (m) for the raw fix `raw` at time t (s)."""
        raw = np.asarray(raw, dtype=float)
        if self.position is None:
            out = raw.copy()
        elif self._last_raw is not None and np.array_equal(raw, self._last_raw):
            out = self.position.copy()                       # target stopped
        else:
            self.speed = self._speed()
            out = raw.copy()
            if np.isfinite(self.speed):
                bound = self.speed * (t - self._last_time)
                offset = raw - self.position
                length = float(np.hypot(*offset))
                if length >= bound:
                    out = self.position + (bound / length) * offset if length > 0 else self.position.copy()
        self._history.append((t, raw.copy() if self.speed_from == "raw" else out.copy()))
        self.position, self._last_raw, self._last_time = out, raw.copy(), t
        return out
