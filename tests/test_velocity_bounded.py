"""Velocity-bounded tracker (paper D) on hand-computed fix sequences: the speed window's
length, its source (raw fixes or tracked positions), the stop rule and gaps without a fix."""

import math

import numpy as np
import pandas as pd
import pytest

from wsnloc.estimators.trackers import velocity_track
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker

# (0, 0) @ 0 s and (1, 0) @ 1 s are accepted (window not yet holding two positions, then 1 m/s
# over 1 m); (3, 0) @ 2 s is 2 m from (1, 0) with R_b = 1 m/s x 1 s: tracked at (2, 0).
# (3, 4) @ 3 s, from (2, 0): offset (1, 4), l = sqrt(17).
PRIMING = [(0.0, 0.0, 0.0), (1.0, 1.0, 0.0), (2.0, 3.0, 0.0)]
LAST = (3.0, 3.0, 4.0)


@pytest.mark.parametrize("window, speed_from, speed", [
    (1, "raw", 2.0),          # last step of raw fixes: 2 m in 1 s
    (2, "raw", 1.5),          # raw (0, 0) -> (1, 0) -> (3, 0): 3 m in 2 s
    (6, "raw", 1.5),          # window not full: all three raw fixes
    (2, "tracked", 1.0),      # tracked (0, 0) -> (1, 0) -> (2, 0): 2 m in 2 s
])
def test_bounded_step_lands_on_the_circle_of_the_window_speed(window, speed_from, speed):
    tracker = VelocityBoundedTracker(window, speed_from)
    assert [tuple(tracker.step(t, (x, y))) for t, x, y in PRIMING] == [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)]
    out = tracker.step(LAST[0], LAST[1:])
    scale = speed * 1.0 / math.sqrt(17.0)                       # R_b / l, R_b = v_hat (3 s - 2 s)
    assert out == pytest.approx([2.0 + scale * 1.0, 0.0 + scale * 4.0], abs=1e-12)
    assert tracker.speed == pytest.approx(speed, abs=1e-12)


def test_a_repeated_fix_keeps_the_position_and_enters_the_window_as_a_zero_step():
    """The raw fix (3, 0) repeated at 3 s: the tracked position stays at (2, 0), though the
    window speed (1.5 m/s) would reach the fix 1 m away. The window (N = 2) then holds
    (1, 0) @ 1 s, (3, 0) @ 2 s, (3, 0) @ 3 s: 2 m in 2 s, so (5, 0) @ 4 s is bounded to (3, 0)."""
    tracker = VelocityBoundedTracker(2)
    outs = [tuple(tracker.step(t, (x, y))) for t, x, y in PRIMING + [(3.0, 3.0, 0.0), (4.0, 5.0, 0.0)]]
    assert outs[:4] == [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (2.0, 0.0)]
    assert outs[4] == pytest.approx((3.0, 0.0), abs=1e-12)


def test_velocity_track_skips_epochs_without_a_fix_and_bounds_over_the_gap():
    """No fix at 2 s: the fix at 3 s is 4 m from (1, 0), R_b = 1 m/s x (3 s - 1 s) = 2 m."""
    fixes = pd.DataFrame({"t": [0.0, 1.0, 2.0, 3.0], "x": [0.0, 1.0, np.nan, 5.0], "y": [0.0, 0.0, 0.0, 0.0]})
    out = velocity_track(fixes, 6, "raw")
    assert list(out.columns) == ["t", "x", "y"] and out["t"].tolist() == [0.0, 1.0, 3.0]
    assert out[["x", "y"]].to_numpy() == pytest.approx(np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]]), abs=1e-12)


@pytest.mark.parametrize("speed_from", ["raw", "tracked"])
@pytest.mark.parametrize("window", [1, 6])
def test_velocity_track_equals_the_tracker_stepped_over_the_finite_fixes(window, speed_from):
    rng = np.random.default_rng(window)
    t = np.arange(80) * 0.5
    xy = np.column_stack([0.3 * t, 0.1 * t]) + rng.normal(0.0, 0.8, (80, 2))
    xy[rng.random(80) < 0.2] = np.nan
    xy[30:35] = xy[29]                                          # target stopped
    tracker = VelocityBoundedTracker(window, speed_from)
    finite = np.isfinite(xy).all(axis=1)
    expected = np.array([[tk, *tracker.step(tk, pk)] for tk, pk in zip(t[finite], xy[finite])])
    out = velocity_track(pd.DataFrame({"t": t, "x": xy[:, 0], "y": xy[:, 1]}), window, speed_from)
    assert out.to_numpy() == pytest.approx(expected, abs=1e-12)


def test_no_fix_gives_an_empty_track():
    fixes = pd.DataFrame({"t": [0.0, 0.5], "x": [np.nan, np.nan], "y": [1.0, np.nan]})
    out = velocity_track(fixes, 6, "raw")
    assert len(out) == 0 and list(out.columns) == ["t", "x", "y"]
