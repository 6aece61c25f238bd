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


def _steps_per_target(ramp_interval_s: float, budget: int) -> int:
    """Moving steps between two target draws.

    The controller's clock is t_move = dt + dt + ... (float sum, reset at each draw); a
    new target is drawn at the first step with t_move >= ramp_interval_s. Returns that
    count c* = #{c >= 0 : T_c < ramp_interval_s}, T_0 = 0, T_c = T_{c-1} + dt (np.cumsum
    adds sequentially, so T_c is the loop's float sum), at most `budget`.
    """
    n = min(math.ceil(ramp_interval_s / STEP_S) + 2, budget)
    clock = np.concatenate([[0.0], np.cumsum(np.full(max(n, 0), STEP_S))])
    return int(np.searchsorted(clock, ramp_interval_s, side="left"))


def _acceleration(s: float, v: float, target: float, stop: float, a_max: float) -> float:
    """Controller output (m/s^2) at arc length s (m), speed v (m/s), for one step.

    v_des = min(target, sqrt(2 a_max d)), d = stop - s (m, >= 0);
    a = clip((v_des - v) / dt, -a_max, a_max), replaced by a = -v^2 / (2 d) when braking
    harder than a_max is needed not to overshoot the stop point. Plain float arithmetic
    and conditional expressions: this runs once per step outside the steady runs.
    """
    remaining = stop - s
    braking = math.sqrt(2.0 * a_max * (0.0 if remaining < 0.0 else remaining))
    v_des = target if target <= braking else braking
    a = (v_des - v) / STEP_S
    a = -a_max if a < -a_max else (a_max if a > a_max else a)
    if remaining > 0 and v > 0 and v * v / (2 * remaining) > a_max:
        a = -v * v / (2 * remaining)
    return a


def _arrived(s, v, stop: float, a_max: float):
    """At the stop point and slower than one step of braking (a_max dt): at rest.
    s in m, v in m/s, floats or arrays (`&` serves both)."""
    return (stop - s <= 1e-6) & (v <= a_max * STEP_S)


def _accelerations(s: np.ndarray, v: np.ndarray, target: float, stop: float, a_max: float) -> np.ndarray:
    """`_acceleration` for arrays of states, with the same float operations in the same order."""
    remaining = stop - s
    braking = np.sqrt(2.0 * a_max * np.where(remaining < 0.0, 0.0, remaining))
    v_des = np.where(target <= braking, target, braking)
    a = (v_des - v) / STEP_S
    a = np.where(a < -a_max, -a_max, np.where(a > a_max, a_max, a))
    with np.errstate(divide="ignore", invalid="ignore"):
        overshoot = (remaining > 0) & (v > 0) & (v * v / (2 * remaining) > a_max)
        return np.where(overshoot, -v * v / (2 * remaining), a)


def _constant_acceleration(s0: float, v0: float, a: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """States s_k (m), v_k (m/s), k = 0..n, of n steps at constant acceleration a (m/s^2).

    v_{k+1} = v_k + a dt, s_{k+1} = (s_k + v_k dt) + a dt^2/2, unclipped. np.cumsum adds
    sequentially, so each value is the float the step-by-step recurrence gives (the
    position sum interleaves the v_k dt and a dt^2/2 terms to keep the loop's order).
    """
    v = np.cumsum(np.concatenate([[v0], np.full(n, a * STEP_S)]))
    terms = np.empty(2 * n + 1)
    terms[0], terms[1::2], terms[2::2] = s0, v[:-1] * STEP_S, a * (0.5 * STEP_S**2)
    return np.cumsum(terms)[::2], v


def _steady_steps(s0: float, v0: float, a: float, n: int, target: float, stop: float, length: float,
                  a_max: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The first m (1 <= m <= n) steps from (s0, v0) that all use acceleration `a`.

    Step k > 0 keeps `a` while its state needs no clipping (s_k <= length, v_k >= 0), the
    cart has not arrived and the controller still outputs exactly `a`. Returns the states
    s_k, v_k for k = 0..m (state m unclipped) and m.
    """
    s, v = _constant_acceleration(s0, v0, a, n)
    steady = (s[1:n] <= length) & (v[1:n] >= 0.0) & ~_arrived(s[1:n], v[1:n], stop, a_max) \
        & (_accelerations(s[1:n], v[1:n], target, stop, a_max) == a)
    m = 1 + int(np.argmin(steady)) if not steady.all() else n
    return s[:m + 1], v[:m + 1], m


class _Recorder:
    """Recorded states, in chunks: runs and rests as arrays, single steps as float lists."""

    def __init__(self):
        self.parts: list[tuple] = []
        self.s, self.v, self.a = [], [], []      # single steps since the last chunk

    def step(self, s: float, v: float, a: float) -> None:
        self.s.append(s)
        self.v.append(v)
        self.a.append(a)

    def run(self, s: np.ndarray, v: np.ndarray, a: float) -> None:
        """Steps at one acceleration a (m/s^2)."""
        self._flush()
        self.parts.append((s, v, np.full(len(s), a)))

    def rest(self, s: float, n: int) -> None:
        """n steps at rest at arc length s (m)."""
        self.run(np.full(n, s), np.zeros(n), 0.0)

    def _flush(self) -> None:
        if self.s:
            self.parts.append((np.array(self.s), np.array(self.v), np.array(self.a)))
            for column in (self.s, self.v, self.a):
                column.clear()

    def trajectory(self) -> Trajectory:
        self._flush()
        s, v, a = (np.concatenate(column) for column in zip(*self.parts))
        return Trajectory(t=np.arange(len(s)) * STEP_S, s=s, v=v, a=a)


def variable_speed(length: float, rng: np.random.Generator, static_start_s: float,
                   ramp_interval_s: float, speed_range_mps, max_accel_mps2: float,
                   stop_s: float, static_end_s: float) -> Trajectory:
    """Random target speed every `ramp_interval_s`, one stop half-way (none for `stop_s` 0:
    the cart moves on without braking), rest at both ends (none for a duration 0).

    A speed controller (`_acceleration`) tracks the target with |a| <= max_accel and brakes
    so as to stop exactly at the half-way point and at the end: v_des = min(target,
    sqrt(2 a_max d)), d being the distance to the next stop point. The state is recorded
    as integrated, so the cart is exactly at rest (v = 0, s constant) during the stops.

    Most steps accelerate at +-a_max or cruise at a = 0 (the controller saturates or sits on
    its target): from such a step on, a run of steps at that acceleration is integrated at
    once (`_steady_steps`) up to the first step where the controller's output changes; the
    other steps are integrated one by one. Both give the same floats as a step-by-step
    loop, so logs stay byte-identical.
    """
    low, high = speed_range_mps
    stops = [length / 2.0, length] if stop_s > 0 else [length]
    dt, a_max = STEP_S, max_accel_mps2
    record = _Recorder()
    record.rest(0.0, int(round(static_start_s / dt)))
    s, v, stop_index = 0.0, 0.0, 0
    steps, budget = 0, int(10 * length / low / dt)
    per_target = _steps_per_target(ramp_interval_s, budget)
    target, since_draw = rng.uniform(low, high), 0
    while steps < budget:
        steps += 1
        stop = stops[stop_index]
        if _arrived(s, v, stop, a_max):
            # Arrived: stop exactly, then hold or finish.
            s, v = stop, 0.0
            if stop_index == len(stops) - 1:
                break
            stop_index += 1
            hold = min(int(round(stop_s / dt)), budget - steps)
            record.rest(s, hold + 1)
            steps += hold
            continue
        if since_draw >= per_target:
            target, since_draw = rng.uniform(low, high), 0
        a = _acceleration(s, v, target, stop, a_max)
        n = min(per_target - since_draw, budget - steps + 1)      # steps left at this target
        if n > 1 and (a == 0.0 or a == a_max or a == -a_max):
            s_run, v_run, m = _steady_steps(s, v, a, n, target, stop, length, a_max)
            record.run(s_run[:m], v_run[:m], a)
            s, v = float(s_run[m]), float(v_run[m])
            steps, since_draw = steps + m - 1, since_draw + m
        else:
            record.step(s, v, a)
            s, v = s + v * dt + a * (0.5 * dt**2), v + a * dt
            since_draw += 1
        s = length if s > length else s
        v = 0.0 if v < 0.0 else v
    record.rest(length, int(round(static_end_s / dt)))
    return record.trajectory()


def for_scenario(scenario: dict, length: float, rng: np.random.Generator) -> Trajectory:
    """Build the trajectory a campaign scenario describes (``motion: constant|variable``).

    `length` is the campaign path's length (m); a scenario with `path_length_m` follows only the
    first path_length_m metres of it (at most `length`). The motion is along the path: a 3-D
    scenario's height profile (`tag_height_m`, `anchor_heights_m`) is the path's (Campaign.for_scenario).
    """
    params = {k: v for k, v in scenario.items() if k not in ("motion", "overrides", "path_length_m", "tag_height_m",
                                                             "anchor_heights_m")}
    part = scenario.get("path_length_m", length)
    if not 0 < part <= length:
        raise ValueError(f"scenario path_length_m = {part:g} m: must lie in (0, {length:.2f}] m (the campaign path)")
    length = part
    if scenario["motion"] == "constant":
        return constant_speed(length, **params)
    return variable_speed(length, rng, **params)


def peak_acceleration(scenario: dict) -> float:
    """The largest |a| (m/s^2) a campaign scenario's motion reaches: speed_mps / accel_time_s on
    the constant-speed ramps (constant_speed), max_accel_mps2 for variable speed (variable_speed)."""
    if scenario["motion"] == "constant":
        return scenario["speed_mps"] / scenario["accel_time_s"]
    return scenario["max_accel_mps2"]
