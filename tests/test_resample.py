"""IMU resampling: why an anti-aliasing filter is needed before going from 500 Hz to 5 Hz."""

import subprocess
import sys
from fractions import Fraction

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from wsnloc.signal.resample import decimate, kaiser_lowpass, resample_imu

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


# decimate re-implements scipy.signal.resample_poly(window=("kaiser", beta), padtype="line"); scipy is the
# reference here only: wsnloc.signal.resample itself must not import it.
# (in Hz, out Hz): the campaign's 500 -> 5 Hz (up 1, down 100), and up > 1 with down > up,
# with down < up, and pure up-sampling.
RATES = [(500.0, 5.0), (500.0, 200.0), (100.0, 150.0), (100.0, 300.0)]
# Shorter than the 500 -> 5 Hz filter (2001 taps), exactly its length, one more, 20 s at 500 Hz.
LENGTHS = [2, 3, 57, 2000, 2001, 2002, 10_000]


def _scipy_reference(x, in_hz, out_hz, beta):
    ratio = Fraction(out_hz / in_hz).limit_denominator(10_000)
    return signal.resample_poly(x, ratio.numerator, ratio.denominator, axis=0,
                                window=("kaiser", beta), padtype="line")


def _channels(n, seed):
    """(n, 4): noise, a ramp plus a 25 Hz tone, gravity offset on z, a small gyro bias."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    x = rng.normal(0.0, 0.3, (n, 4))
    x[:, 0] += 0.5 * t + 0.2 * np.cos(2 * np.pi * 25.0 * t)
    x[:, 2] += 9.80665
    x[:, 3] += 0.01
    return x


@pytest.mark.parametrize("in_hz, out_hz", RATES)
@pytest.mark.parametrize("n", LENGTHS)
def test_decimate_equals_scipy_resample_poly(in_hz, out_hz, n):
    x = _channels(n, seed=n)
    for beta in (0.0, 5.0, 8.0, 14.0):
        ours, ref = decimate(x, in_hz, out_hz, beta), _scipy_reference(x, in_hz, out_hz, beta)
        assert ours.shape == ref.shape
        assert np.abs(ours - ref).max() <= 1e-12 * np.abs(x).max(), (beta, np.abs(ours - ref).max())


@pytest.mark.parametrize("in_hz, out_hz", RATES)
def test_filter_is_scipy_firwin_scaled_by_up(in_hz, out_hz):
    ratio = Fraction(out_hz / in_hz).limit_denominator(10_000)
    max_rate = max(ratio.numerator, ratio.denominator)
    ref = ratio.numerator * signal.firwin(20 * max_rate + 1, 1 / max_rate, window=("kaiser", 8.0))
    assert np.abs(kaiser_lowpass(ratio.numerator, ratio.denominator, 8.0) - ref).max() <= 1e-15


def test_decimate_keeps_a_one_dimensional_signal_and_an_empty_one():
    x = _channels(3000, seed=1)[:, 2]
    assert np.abs(decimate(x, FS, 5.0, 8.0) - _scipy_reference(x, FS, 5.0, 8.0)).max() <= 1e-12 * 9.81
    assert decimate(np.empty((0, 4)), FS, 5.0, 8.0).shape == (0, 4)


def test_single_sample_is_held_where_scipy_gives_nan():
    x = np.array([[0.1, -0.2, 9.80665, 0.01]])
    assert np.isnan(_scipy_reference(x, FS, 5.0, 8.0)).all()
    assert decimate(x, FS, 5.0, 8.0) == pytest.approx(x, abs=1e-12)


def test_equal_rates_copy_and_a_zero_rate_is_refused():
    x = _channels(10, seed=2)
    same = decimate(x, FS, FS, 8.0)
    assert np.array_equal(same, x) and same is not x
    with pytest.raises(ValueError, match="500.0 Hz to 0.0 Hz"):
        decimate(x, FS, 0.0, 8.0)


def test_resample_module_loads_no_scipy():
    probe = "import sys, wsnloc.signal.resample; print(sorted(m for m in sys.modules if m.startswith('scipy')))"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
