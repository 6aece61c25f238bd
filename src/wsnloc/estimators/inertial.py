"""Inertial pipelines (paper B) and the measured-acceleration input of the PVA filter.

Dead reckoning integrates the 5 Hz IMU from the start pose (inertial.dead_reckoning);
the fused pipelines predict with each 5 Hz step's dead-reckoning displacement and update
with the fix that arrived during the step (filters.steady_state): a steady-state gain
K = P (P + R)^-1 from the DARE for one update per fix period, or the classical
time-varying gain from P0 = 0 (the start pose is known).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.errors import WsnlocError
from wsnloc.estimators.run_data import RunData
from wsnloc.filters.numerics import Guards
from wsnloc.filters.steady_state import fuse, steady_state_gain
from wsnloc.inertial.dead_reckoning import dead_reckon, floor_acceleration, static_bias


def start_pose(data: RunData, why: str) -> tuple[float, float, float]:
    """(x0, y0, heading0) from the campaign path: the inertial pipelines start from the known pose."""
    if data.campaign is None or data.campaign.path is None:
        raise WsnlocError(f"{data.name}: {why} needs the start pose, from a campaign file with a path")
    return data.campaign.path.start_pose()


def dead_reckoning(data: RunData, static_start_s: float) -> pd.DataFrame:
    """(t, x, y, vx, vy, heading) by dead reckoning of the run's 5 Hz IMU."""
    def build():
        imu = data.require("imu_5hz", "dead reckoning").reset_index(drop=True)
        x0, y0, heading0 = start_pose(data, "dead reckoning")
        return dead_reckon(imu, x0, y0, heading0, static_bias(imu, static_start_s))
    return data.cached(("dead_reckoning", static_start_s), build)


def align_fixes(step_times: np.ndarray, fixes: pd.DataFrame) -> np.ndarray:
    """(N - 1, 2): the fix that arrived during step k (t_k, t_{k+1}], NaN where none."""
    out = np.full((len(step_times) - 1, 2), np.nan)
    t, x, y = (fixes[c].to_numpy(float) for c in ("t", "x", "y"))
    valid = ~(np.isnan(t) | np.isnan(x) | np.isnan(y))       # fixes.dropna() of the (t, x, y) rows
    index = np.searchsorted(step_times, t[valid], side="left") - 1
    inside = (index >= 0) & (index < len(out))
    out[index[inside]] = np.column_stack([x[valid], y[valid]])[inside]
    return out


def fused(data: RunData, fixes: pd.DataFrame, p: dict, steady_state: bool) -> pd.DataFrame:
    """Dead reckoning fused with the fixes; Q per 5 Hz step = sigma_p^2 I, R = sigma_fix^2 I. The
    classical filter's numerical guards (filters.numerics: updates skipped) go to the attrs."""
    dr = dead_reckoning(data, p["static_start_s"])
    t = dr["t"].to_numpy()
    if len(t) < 2:
        raise WsnlocError(f"{data.name}: the 5 Hz IMU has fewer than 2 samples")
    Q_step = np.eye(2) * p["process_sigma_m"] ** 2
    R = np.eye(2) * p["fix_sigma_m"] ** 2
    xy = np.column_stack([dr["x"].to_numpy(float), dr["y"].to_numpy(float)])
    start, displacements = xy[0], np.diff(xy, axis=0)
    aligned = align_fixes(t, fixes)
    guards = None if steady_state else Guards()      # the steady-state filter has no guard
    if steady_state:
        steps_per_update = p["epoch_s"] / float(np.median(np.diff(t)))
        positions = fuse(displacements, aligned, start, Q_step, R, gain=steady_state_gain(Q_step * steps_per_update, R))
    else:
        positions = fuse(displacements, aligned, start, Q_step, R, P0=np.zeros((2, 2)), guards=guards)
    out = pd.DataFrame({"t": t, "x": positions[:, 0], "y": positions[:, 1]})
    out.attrs.update(guards.attrs() if guards else {})
    return out


def floor_input(data: RunData, static_start_s: float, heading0: float | None = None) -> pd.DataFrame:
    """Floor-frame acceleration (t, ax, ay; m/s^2) of the 5 Hz IMU: bias measured at rest
    removed, rotated with the gyro heading from heading0 (rad; None: the campaign path's start
    heading, a known start pose) (the PVA model's input). Built once per run, static_start_s and
    heading0: every PVA cell of the run reads it."""
    def build():
        imu = data.require("imu_5hz", "the PVA model's acceleration input")
        start = start_pose(data, "the PVA model's acceleration input")[2] if heading0 is None else heading0
        return floor_acceleration(imu, start, static_bias(imu, static_start_s))
    return data.cached(("floor_input", static_start_s, heading0), build)


HEADING_BASELINE_M = 1.0    # ~30x a Cricket fix's error, ~1x a UWB fix's: the direction is known to a few degrees
                            # (Cricket) or a few tens (UWB); shorter baselines are dominated by the fix noise


def heading_from_fixes(fixes: pd.DataFrame, baseline_m: float = HEADING_BASELINE_M) -> float | None:
    """Initial heading (rad, atan2 convention) measured from the run's first position fixes: from
    the start point m_0 (median of the first 3 fixes) to the first running median of 3 consecutive
    fixes at least baseline_m from m_0 (medians: one reflected range does not set the heading).
    None when the fixes never move that far. The mobile is assumed to drive forward (body x along
    its motion) over that first stretch."""
    xy = fixes[["x", "y"]].to_numpy(float)
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if len(xy) < 4:
        return None
    medians = np.median(np.lib.stride_tricks.sliding_window_view(xy, 3, axis=0), axis=-1)   # (n - 2, 2)
    away = np.hypot(*(medians - medians[0]).T) >= baseline_m
    if not away.any():
        return None
    dx, dy = medians[int(np.argmax(away))] - medians[0]
    return float(np.arctan2(dy, dx))


def epoch_inputs(acc: pd.DataFrame, times: np.ndarray, columns: tuple[str, str] = ("ax", "ay")) -> np.ndarray:
    """(len(times), 2) mean of two input columns over each period (t_k-1, t_k]: the floor-frame
    acceleration (ax, ay) by default, or the odometry's (v_mps, yaw_rate_rps); NaN without samples."""
    index = np.searchsorted(times, acc["t"].to_numpy(), side="left")
    valid = index < len(times)
    out = np.full((len(times), 2), np.nan)
    counts = np.bincount(index[valid], minlength=len(times))
    for j, column in enumerate(columns):
        sums = np.bincount(index[valid], weights=acc[column].to_numpy()[valid], minlength=len(times))
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, j] = sums / counts
    return out
