"""Resample an irregular IMU stream (about 500 Hz) to a low uniform rate (5 Hz).

Two steps:
1. Interpolate linearly onto a uniform grid at `grid_rate_hz` (repairs timestamp jitter
   and the occasional dropped sample).
2. Anti-aliasing low-pass and decimation in one polyphase FIR (scipy.signal.resample_poly,
   Kaiser window). Plain sub-sampling would fold the 15-40 Hz drive vibration onto low
   frequencies: a 25 Hz tone sampled every 0.2 s is a constant offset, indistinguishable
   from a real acceleration. The filter keeps 0-~2 Hz motion and removes the vibration.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pandas as pd
from scipy import signal

CHANNELS = ("ax", "ay", "az", "gz")


def uniform_grid(t: np.ndarray, values: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation of `values` (N, C) sampled at times t (s) onto k / rate_hz."""
    start = np.ceil(t[0] * rate_hz) / rate_hz
    grid = start + np.arange(int(np.floor((t[-1] - start) * rate_hz)) + 1) / rate_hz
    out = np.column_stack([np.interp(grid, t, values[:, c]) for c in range(values.shape[1])])
    return grid, out


def decimate(values: np.ndarray, in_rate_hz: float, out_rate_hz: float, kaiser_beta: float) -> np.ndarray:
    """Polyphase low-pass + rate change by the rational factor out/in, zero phase.

    The FIR (half-length 10 * max(up, down) taps, Kaiser window `kaiser_beta`) cuts off at
    the output Nyquist frequency; edges are padded with a fitted line to avoid transients
    on signals with an offset (gravity on z).
    """
    ratio = Fraction(out_rate_hz / in_rate_hz).limit_denominator(10_000)
    return signal.resample_poly(values, ratio.numerator, ratio.denominator, axis=0,
                                window=("kaiser", kaiser_beta), padtype="line")


def resample_imu(imu: pd.DataFrame, rate_hz: float, grid_rate_hz: float, max_gap_s: float,
                 kaiser_beta: float) -> pd.DataFrame:
    """IMU table (t, ax, ay, az, gz) -> uniform table at `rate_hz` with an `in_gap` flag.

    An output sample is flagged when it lies inside a hole of the raw stream longer than
    `max_gap_s` (its value there is interpolated across the hole, not measured).
    """
    columns = ["t", *CHANNELS, "in_gap"]
    if len(imu) < 2:
        return pd.DataFrame({c: pd.Series(dtype=bool if c == "in_gap" else float) for c in columns})
    t = imu["t"].to_numpy(dtype=float)
    grid, uniform = uniform_grid(t, imu[list(CHANNELS)].to_numpy(dtype=float), grid_rate_hz)
    low = decimate(uniform, grid_rate_hz, rate_hz, kaiser_beta)
    t_out = grid[0] + np.arange(len(low)) / rate_hz
    gaps = np.flatnonzero(np.diff(t) > max_gap_s)
    in_gap = np.zeros(len(t_out), dtype=bool)
    for g in gaps:
        in_gap |= (t_out > t[g]) & (t_out < t[g + 1])
    frame = pd.DataFrame(low, columns=list(CHANNELS))
    frame.insert(0, "t", t_out)
    frame["in_gap"] = in_gap
    return frame
