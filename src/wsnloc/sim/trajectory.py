"""Motion of the mobile along its path: arc length s(t), speed v(t), acceleration a(t).

Kinematics are integrated on a fine time grid (1 ms) with piecewise-constant
acceleration: s_{k+1} = s_k + v_k dt + a_k dt^2 / 2, v_{k+1} = v_k + a_k dt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

STEP_S = 0.001


@dataclass
class Trajectory:
    """Sampled motion; times in s from the start of logging, s in m, v in m/s, a in m/s^2."""

    t: np.ndarray
    s: np.ndarray
    v: np.ndarray
    a: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, times) -> dict[str, np.ndarray]:
        """Linear interpolation of s and v; acceleration held from the previous step."""
        times = np.asarray(times, dtype=float)
        idx = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, len(self.t) - 1)
        return {
            "s": np.interp(times, self.t, self.s),
            "v": np.interp(times, self.t, self.v),
            "a": self.a[idx],
        }


def _integrate(accel: np.ndarray) -> Trajectory:
    n = len(accel)
    v = np.concatenate([[0.0], np.cumsum(accel) * STEP_S])
    s = np.concatenate([[0.0], np.cumsum(v[:-1] * STEP_S + 0.5 * accel * STEP_S**2)])
    t = np.arange(n + 1) * STEP_S
    return Trajectory(t=t, s=s, v=v, a=np.concatenate([accel, [0.0]]))


def constant_speed(length: float, static_start_s: float, accel_time_s: float,
                   speed_mps: float, static_end_s: float) -> Trajectory:
    """Rest, accelerate to `speed_mps` in `accel_time_s`, cruise, brake symmetrically, rest."""
    accel = speed_mps / accel_time_s
    ramp_distance = speed_mps * accel_time_s          # accel + decel ramps together
    if ramp_distance > length:
        raise ValueError("path too short for the requested speed and acceleration time")
    cruise_s = (length - ramp_distance) / speed_mps
    durations = [static_start_s, accel_time_s, cruise_s, accel_time_s, static_end_s]
    values = [0.0, accel, 0.0, -accel, 0.0]
    steps = np.round(np.array(durations) / STEP_S).astype(int)
    traj = _integrate(np.repeat(values, steps))
    traj.s = np.clip(traj.s, 0.0, length)
    traj.v = np.maximum(traj.v, 0.0)
    return traj


def variable_speed(length: float, rng: np.random.Generator, static_start_s: float,
                   ramp_interval_s: float, speed_range_mps, max_accel_mps2: float,
                   stop_s: float, static_end_s: float) -> Trajectory:
    """Random target speed every `ramp_interval_s`, one stop half-way, rest at both ends.

    A speed controller tracks the target with |a| <= max_accel and brakes so as to stop
    exactly at the half-way point and at the end: v_des = min(target, sqrt(2 a_max d)),
    d being the distance to the next stop point. The state is recorded as integrated,
    so the cart is exactly at rest (v = 0, s constant) during the stops.
    """
    low, high = speed_range_mps
    stops = [length / 2.0, length]
    dt, a_max = STEP_S, max_accel_mps2
    half_dt2 = 0.5 * dt**2                  # 0.5 a dt^2 == a (0.5 dt^2) exactly (0.5 is a power of 2)
    two_a_max = 2.0 * a_max
    arrived_speed = a_max * dt              # slower than one step of braking: at rest
    rest_start = int(round(static_start_s / dt))
    s_list, v_list, a_list = [0.0] * rest_start, [0.0] * rest_start, [0.0] * rest_start
    record_s, record_v, record_a = s_list.append, v_list.append, a_list.append
    s, v, t_move, stop_index = 0.0, 0.0, 0.0, 0
    target = rng.uniform(low, high)
    # Plain float arithmetic and conditional expressions instead of numpy / min / max: this
    # loop runs ~10^5 times per run (the simulator's hot spot) and is 2x faster this way
    # (three lists of floats, not a list of tuples: floats are not tracked by the garbage
    # collector). A stop (s constant, v = a = 0) is recorded in one go.
    steps, budget = 0, int(10 * length / low / dt)
    while steps < budget:
        steps += 1
        remaining = stops[stop_index] - s
        if remaining <= 1e-6 and v <= arrived_speed:
            # Arrived: stop exactly, then hold or finish.
            s, v = stops[stop_index], 0.0
            if stop_index == len(stops) - 1:
                break
            stop_index += 1
            hold = min(int(round(stop_s / dt)), budget - steps)
            s_list += [s] * (hold + 1)
            v_list += [0.0] * (hold + 1)
            a_list += [0.0] * (hold + 1)
            steps += hold
            continue
        if t_move >= ramp_interval_s:
            target, t_move = rng.uniform(low, high), 0.0
        braking = math.sqrt(two_a_max * (0.0 if remaining < 0.0 else remaining))
        v_des = target if target <= braking else braking
        a = (v_des - v) / dt                                  # clipped to [-a_max, a_max]
        a = -a_max if a < -a_max else (a_max if a > a_max else a)
        if remaining > 0 and v > 0 and v * v / (2 * remaining) > a_max:
            a = -v * v / (2 * remaining)   # never overshoot a stop point
        t_move += dt
        record_s(s)
        record_v(v)
        record_a(a)
        s = s + v * dt + a * half_dt2
        s = length if s > length else s
        v = v + a * dt
        v = 0.0 if v < 0.0 else v
    rest_end = int(round(static_end_s / dt))
    s_list += [length] * rest_end
    v_list += [0.0] * rest_end
    a_list += [0.0] * rest_end
    t = np.arange(len(s_list)) * STEP_S
    return Trajectory(t=t, s=np.asarray(s_list), v=np.asarray(v_list), a=np.asarray(a_list))


def for_scenario(scenario: dict, length: float, rng: np.random.Generator) -> Trajectory:
    """Build the trajectory a campaign scenario describes (``motion: constant|variable``)."""
    params = {k: v for k, v in scenario.items() if k not in ("motion", "overrides")}
    if scenario["motion"] == "constant":
        return constant_speed(length, **params)
    return variable_speed(length, rng, **params)
