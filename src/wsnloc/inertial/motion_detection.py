"""Accelerometer motion detection (paper A).

For each estimation period (t_k - period, t_k], the mean of | ||f|| - g_ref | over the raw
accelerometer samples, with f the specific force (m/s^2) and g_ref the mean norm measured
while the mobile is known to rest at the start (absorbs the sensor's scale and bias on
the vertical axis). Below `threshold` the mobile is declared static for that epoch.
Works on the raw-rate stream: driving vibration is what reveals motion at constant speed,
and the 5 Hz low-pass would remove it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def gravity_reference(imu: pd.DataFrame, static_start_s: float) -> float:
    norm = np.sqrt(imu["ax"] ** 2 + imu["ay"] ** 2 + imu["az"] ** 2)
    still = imu["t"] <= imu["t"].iloc[0] + static_start_s
    return float(norm[still].mean())


def activity(imu: pd.DataFrame, epoch_times: np.ndarray, period: float, g_ref: float) -> np.ndarray:
    """Mean | ||f|| - g_ref | per epoch (m/s^2); NaN for an epoch without samples."""
    t = imu["t"].to_numpy(float)
    deviation = np.abs(np.sqrt(imu["ax"] ** 2 + imu["ay"] ** 2 + imu["az"] ** 2).to_numpy() - g_ref)
    index = np.searchsorted(epoch_times, t, side="left")
    valid = (index < len(epoch_times)) & (t > epoch_times[np.minimum(index, len(epoch_times) - 1)] - period)
    sums = np.bincount(index[valid], weights=deviation[valid], minlength=len(epoch_times))
    counts = np.bincount(index[valid], minlength=len(epoch_times))
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / counts


def static_epochs(imu: pd.DataFrame, epoch_times: np.ndarray, period: float, threshold: float,
                  static_start_s: float) -> np.ndarray:
    """Boolean per epoch: True where the mobile is declared static (no IMU data: not static)."""
    if len(imu) == 0:
        return np.zeros(len(epoch_times), dtype=bool)
    level = activity(imu, epoch_times, period, gravity_reference(imu, static_start_s))
    return np.nan_to_num(level, nan=np.inf) < threshold
