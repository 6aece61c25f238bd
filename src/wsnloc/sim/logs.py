"""Log writers shared by the campaign simulators: IMU, truth, run directory and meta.yaml."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from wsnloc import __version__
from wsnloc.campaign import Campaign
from wsnloc.sim import imu as imu_model
from wsnloc.sim.trajectory import Trajectory

GENERATOR = "wsnloc-sim"


def positions(campaign: Campaign, traj: Trajectory, times_s: np.ndarray) -> dict:
    """Path state (s, v, a) and pose (x, y, heading, curvature) at the given times."""
    state = traj.at(times_s)
    pose = campaign.path.evaluate(state["s"])
    return {**state, **pose, "xy": np.column_stack([pose["x"], pose["y"]])}


def imu_lines(campaign: Campaign, traj: Trajectory, rng, noise_model: str, clock_ms: int) -> list[str]:
    """`imu.log`: sensor-clock time (3 decimals, jittered, some samples dropped) and raw counts."""
    spec = dict(campaign.section("imu"), noise_model=noise_model)
    g = campaign.spec["gravity_mps2"]
    period_ms = 1000.0 / spec["rate_hz"]
    nominal = np.arange(0.0, traj.duration * 1000, period_ms)
    t_ms = nominal + rng.normal(0.0, spec["timestamp_jitter_ms"], len(nominal))
    kept = rng.random(len(t_ms)) >= spec["drop_rate"]
    t_ms = np.sort(t_ms[kept])
    state = positions(campaign, traj, t_ms / 1000.0)
    force, yaw_rate = imu_model.body_motion(state["v"], state["a"], state["curvature"], g)
    accel, gyro = imu_model.sensor_readings(t_ms / 1000.0, force, yaw_rate, state["v"], spec, g, rng)
    acc_counts, gyro_counts = imu_model.to_counts(accel, gyro, spec, g)
    header = [f"# {campaign.format}-imu v1",
              f"# accel_lsb_per_g={spec['accel_lsb_per_g']:g} gyro_lsb_per_dps={spec['gyro_lsb_per_dps']:g}",
              "# t_ms ax ay az gz"]
    columns = [(t_ms + clock_ms).tolist(), *np.asarray(acc_counts).T.tolist(), np.asarray(gyro_counts).tolist()]
    return header + list(map("%.3f %d %d %d %d".__mod__, zip(*columns)))


def truth_lines(campaign: Campaign, traj: Trajectory, clock_ms: int, column: str) -> list[str]:
    """`truth.log`: position along the path (`rail_m` or `path_m`) at the truth rate."""
    spec = campaign.section("truth")
    period_ms = 1000.0 / spec["rate_hz"]
    t_ms = np.arange(0.0, traj.duration * 1000 + 1e-9, period_ms)
    s = np.round(traj.at(t_ms / 1000.0)["s"] / spec["resolution_m"]) * spec["resolution_m"]
    decimals = max(0, int(round(-np.log10(spec["resolution_m"]))))
    lines = [f"# {campaign.format}-truth v1", f"# t_ms {column}"]
    lines += [f"{int(round(t)) + clock_ms} {v:.{decimals}f}" for t, v in zip(t_ms.tolist(), s.tolist())]
    return lines


def write_run(out_dir: Path, files: dict[str, list[str]], campaign: Campaign, scenario: str,
              seeds: np.random.SeedSequence, meta: dict) -> Path:
    """Write the log files and meta.yaml (no wall-clock date, so reruns are byte-identical)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, lines in files.items():
        (out_dir / name).write_text("\n".join(lines) + "\n", encoding="ascii")
    record = {
        "generator": f"{GENERATOR} {__version__}",
        "campaign": campaign.name,
        "scenario": scenario,
        "seed_entropy": [int(x) for x in np.atleast_1d(seeds.entropy)],
        "date": None,
        "notes": "simulated campaign; no wall-clock date is written so that reruns are byte-identical",
        **meta,
    }
    (out_dir / "meta.yaml").write_text(yaml.safe_dump(record, sort_keys=True), encoding="ascii")
    return out_dir
