"""Resample an irregular IMU stream (about 500 Hz) to a low uniform rate (5 Hz).

Two steps:
1. Interpolate linearly onto a uniform grid at `grid_rate_hz` (repairs timestamp jitter
   and the occasional dropped sample).
2. Anti-aliasing low-pass and decimation in one polyphase FIR (Kaiser-windowed sinc). Plain
   sub-sampling would fold the 15-40 Hz drive vibration onto low frequencies: a 25 Hz tone
   sampled every 0.2 s is a constant offset, indistinguishable from a real acceleration. The
   filter keeps 0-~2 Hz motion and removes the vibration.

Step 2 computes what scipy.signal.resample_poly(x, up, down, window=("kaiser", beta),
padtype="line") computes, in numpy only: importing scipy.signal costs about 1 s per ingest
job, more than the filtering itself.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pandas as pd

CHANNELS = ("ax", "ay", "az", "gz")


def uniform_grid(t: np.ndarray, values: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation of `values` (N, C) sampled at times t (s) onto k / rate_hz."""
    start = np.ceil(t[0] * rate_hz) / rate_hz
    grid = start + np.arange(int(np.floor((t[-1] - start) * rate_hz)) + 1) / rate_hz
    out = np.column_stack([np.interp(grid, t, values[:, c]) for c in range(values.shape[1])])
    return grid, out


def kaiser_lowpass(up: int, down: int, kaiser_beta: float) -> np.ndarray:
    """Zero-phase low-pass FIR for a rate change by up/down (taps k = 0 .. 2H, H = 10 max(up, down)).

    h[k] = up * w[k] sinc(f_c (k - H)) / sum_j w[j] sinc(f_c (j - H)), with f_c = 1 / max(up, down)
    the cut-off relative to the Nyquist frequency of the up-sampled stream, sinc(u) =
    sin(pi u) / (pi u) and w the Kaiser window of length 2H + 1 and shape `kaiser_beta`: unit
    gain at 0 Hz per output phase (scipy: up * firwin(2H + 1, f_c, window=("kaiser", beta))).
    """
    max_rate = max(up, down)
    half_len = 10 * max_rate
    taps = np.sinc((np.arange(2 * half_len + 1) - half_len) / max_rate) * np.kaiser(2 * half_len + 1, kaiser_beta)
    return up * taps / taps.sum()


def line_extended(x: np.ndarray, first: int, stop: int) -> np.ndarray:
    """Samples i = first .. stop - 1 of the rows x (C, n) continued beyond both ends by a line.

    x_i = x_0 + i s for i < 0 and x_{n-1} + (i - n + 1) s for i >= n, with s = (x_{n-1} - x_0) / (n - 1)
    the slope (per sample) of the line through the first and last sample; s = 0 when n = 1
    (there scipy's "line" padding divides by zero and returns NaN).
    """
    n = x.shape[1]
    slope = (x[:, -1:] - x[:, :1]) / (n - 1) if n > 1 else np.zeros_like(x[:, :1])
    before = x[:, :1] + np.arange(first, min(0, stop)) * slope
    after = x[:, -1:] + (np.arange(max(n, first), stop) - (n - 1)) * slope
    return np.concatenate([before, x[:, max(first, 0):max(min(stop, n), 0)], after], axis=1)


def phase_taps(h: np.ndarray, up: int, down: int, phase: int) -> tuple[int, np.ndarray]:
    """Input index i0 = ceil((phase down - H) / up) of the first sample that output `phase` reads,
    and its taps g[q] = h[H + phase down - (i0 + q) up], q = 0 .. 2H // up (0 outside h).

    Output m = phase + a up reads the same taps on inputs i0 + a down + q (a = 0, 1, ...).
    """
    half_len = (len(h) - 1) // 2
    first = -((half_len - phase * down) // up)
    index = half_len + phase * down - first * up - up * np.arange(2 * half_len // up + 1)
    return first, np.where(index >= 0, h[np.maximum(index, 0)], 0.0)


def strided_fir(x: np.ndarray, taps: np.ndarray, stride: int, count: int) -> np.ndarray:
    """y[:, a] = sum_q taps[q] x[:, a stride + q] for a = 0 .. count - 1 (rows x: C channels).

    Cut x into blocks of `stride` samples, B[b, j] = x[b stride + j], and the taps, zero-padded
    to R = ceil(len(taps) / stride) blocks, into G[r, j] = taps[r stride + j]: then
    y[a] = sum_r P[a + r, r] with P = B G^T, one matrix product instead of `count`
    overlapping windows. x needs at least (count - 1 + R) stride samples.
    """
    n_blocks = -(-len(taps) // stride)
    padded = np.zeros(n_blocks * stride)
    padded[:len(taps)] = taps
    rows = count - 1 + n_blocks
    products = x[:, :rows * stride].reshape(x.shape[0], rows, stride) @ padded.reshape(n_blocks, stride).T
    return sum(products[:, r:r + count, r] for r in range(n_blocks))


def decimate(values: np.ndarray, in_rate_hz: float, out_rate_hz: float, kaiser_beta: float) -> np.ndarray:
    """Polyphase low-pass + rate change along axis 0 by the rational factor up/down = out/in, zero phase.

    Output m (at time m / out_rate_hz from the first input sample) is the FIR `kaiser_lowpass`
    centred on it in the stream up-sampled by zero insertion:
        y[m] = sum_i h[H + m down - i up] x_i,   i = ceil((m down - H) / up) .. floor((m down + H) / up),
    with x_i beyond the record continued by `line_extended` (no edge transient on an offset such
    as gravity on z); ceil(n up / down) outputs. Only these outputs are computed: outputs
    m = b, b + up, ... share one tap phase b and read input windows `down` samples apart.
    Equals scipy.signal.resample_poly(values, up, down, axis=0, window=("kaiser", kaiser_beta),
    padtype="line") to rounding (except n = 1, see `line_extended`).
    """
    ratio = Fraction(out_rate_hz / in_rate_hz).limit_denominator(10_000)
    if ratio <= 0:
        raise ValueError(f"cannot resample from {in_rate_hz} Hz to {out_rate_hz} Hz")
    up, down = ratio.numerator, ratio.denominator
    values = np.asarray(values, dtype=float)
    if up == down == 1:
        return values.copy()
    n = values.shape[0]
    n_out = -(-n * up // down)
    x = np.ascontiguousarray(values.reshape(n, math.prod(values.shape[1:])).T)
    out = np.empty((x.shape[0], n_out))
    h = kaiser_lowpass(up, down, kaiser_beta)
    for phase in range(min(up, n_out)):
        first, taps = phase_taps(h, up, down, phase)
        count = len(range(phase, n_out, up))
        blocks = count - 1 + -(-len(taps) // down)
        out[:, phase::up] = strided_fir(line_extended(x, first, first + blocks * down), taps, down, count)
    return out.T.reshape(n_out, *values.shape[1:])


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
