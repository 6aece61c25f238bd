"""IMU resampling: why an anti-aliasing filter is needed before going from 500 Hz to 5 Hz."""

import numpy as np
import pandas as pd
import pytest

from wsnloc.signal.resample import resample_imu

FS = 500.0


def _imu(t, ax):
    zeros = np.zeros_like(t)
    return pd.DataFrame({"t": t, "ax": ax, "ay": zeros, "az": zeros + 9.80665, "gz": zeros})


def _interior(frame, t_from, t_to):
    return frame[(frame["t"] > t_from) & (frame["t"] < t_to)]


def test_vibration_tone_is_removed_while_naive_subsampling_aliases_it():
    t = np.arange(0.0, 120.0, 1 / FS)
    tone = 0.2 * np.cos(2 * np.pi * 25.0 * t + 0.4)          # 25 Hz drive vibration
    naive = tone[:: int(FS / 5)]
    assert np.ptp(naive) < 1e-9 and abs(naive.mean()) > 0.15    # sub-sampling: a constant offset
    out = _interior(resample_imu(_imu(t, tone), 5.0, FS, 0.1, 8.0), 10, 110)
    attenuation_db = 20 * np.log10(np.abs(out["ax"]).max() / 0.2)
    assert attenuation_db <= -40.0


def test_slow_motion_passes_within_one_percent():
    t = np.arange(0.0, 120.0, 1 / FS)
    motion = 0.3 * np.sin(2 * np.pi * 0.2 * t)
    out = _interior(resample_imu(_imu(t, motion), 5.0, FS, 0.1, 8.0), 10, 110)
    expected = 0.3 * np.sin(2 * np.pi * 0.2 * out["t"])
    assert np.abs(out["ax"] - expected).max() <= 0.01 * 0.3
    assert out["az"].to_numpy() == pytest.approx(9.80665, abs=1e-6)   # offsets are preserved


def test_jitter_and_dropped_samples_give_a_uniform_grid():
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 60.0, 1 / FS) + rng.normal(0, 2e-5, 30000)
    keep = rng.random(len(t)) > 0.001
    t = np.sort(t[keep])
    out = resample_imu(_imu(t, 0.1 * np.sin(2 * np.pi * 0.2 * t)), 5.0, FS, 0.1, 8.0)
    assert np.diff(out["t"]) == pytest.approx(np.full(len(out) - 1, 0.2))
    assert not out["in_gap"].any()


def test_long_holes_are_flagged():
    t = np.arange(0.0, 30.0, 1 / FS)
    t = t[(t < 10.05) | (t > 11.05)]          # a 1 s hole, from 10.048 s to 11.052 s
    out = resample_imu(_imu(t, np.zeros_like(t)), 5.0, FS, 0.1, 8.0)
    flagged = out.loc[out["in_gap"], "t"]
    assert flagged.to_numpy() == pytest.approx([10.2, 10.4, 10.6, 10.8, 11.0])


def test_too_short_stream_gives_empty_table():
    out = resample_imu(_imu(np.array([0.0]), np.array([1.0])), 5.0, FS, 0.1, 8.0)
    assert len(out) == 0 and list(out.columns) == ["t", "ax", "ay", "az", "gz", "in_gap"]
