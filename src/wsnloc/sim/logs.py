"""Log writers shared by the campaign simulators: IMU, truth, run directory and meta.yaml."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
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


def _scaled_integers(values: np.ndarray, decimals: int) -> np.ndarray:
    """round(|x| 10^decimals) as int64, rounded as Python's '%.{decimals}f' rounds (exact value, ties even).

    y = fl(|x| 10^d) is within y 2^-53 of the exact product, so np.rint(y) is that rounding
    unless y's fraction is within y 2^-52 of 1/2; those few values are rounded by Python's
    own formatter. Needs |x| 10^d < 2^52.
    """
    scaled = np.abs(values) * 10.0**decimals
    if scaled.size and not scaled.max() < 2.0**52:
        raise ValueError(f"values too large for {decimals} decimals")
    out = np.rint(scaled).astype(np.int64)
    close = np.abs(scaled - np.floor(scaled) - 0.5) <= scaled * 2.0**-52
    for k in np.flatnonzero(close).tolist():
        out[k] = int(f"{abs(values[k]):.{decimals}f}".replace(".", ""))
    return out


def _text(values: np.ndarray, decimals: int) -> pa.Array:
    """Strings of `values` as '%d' (integer array) or '%.{decimals}f' (float array) writes them:
    sign (of a float: its sign bit, as Python writes '-0.000'), whole part, '.', decimals."""
    if np.issubdtype(values.dtype, np.integer):
        return pc.cast(pa.array(values), pa.string())
    whole, fraction = np.divmod(_scaled_integers(values, decimals), 10**decimals)
    text = pc.cast(pa.array(whole), pa.string())
    if decimals:
        text = pc.binary_join_element_wise(text, pc.utf8_lpad(pc.cast(pa.array(fraction), pa.string()), decimals, "0"),
                                           ".")
    return pc.if_else(pa.array(np.signbit(values)), pc.binary_join_element_wise("-", text, ""), text)


def format_rows(columns: list[tuple[np.ndarray, int]]) -> list[str]:
    """Lines of space-separated numbers, column = (values, decimals): byte for byte what
    '%d' (integer array) or '%.{decimals}f' (float array) writes, built with Arrow's
    vectorised string kernels instead of one Python format call per line."""
    return pc.binary_join_element_wise(*(_text(np.asarray(v), d) for v, d in columns), " ").to_pylist()


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
    acc_counts = np.asarray(acc_counts)
    return header + format_rows([(t_ms + clock_ms, 3), *((column, 0) for column in acc_counts.T),
                                 (np.asarray(gyro_counts), 0)])


def truth_lines(campaign: Campaign, traj: Trajectory, clock_ms: int, column: str) -> list[str]:
    """`truth.log`: position along the path (`rail_m` or `path_m`) at the truth rate."""
    spec = campaign.section("truth")
    period_ms = 1000.0 / spec["rate_hz"]
    t_ms = np.arange(0.0, traj.duration * 1000 + 1e-9, period_ms)
    s = np.round(traj.at(t_ms / 1000.0)["s"] / spec["resolution_m"]) * spec["resolution_m"]
    decimals = max(0, int(round(-np.log10(spec["resolution_m"]))))
    lines = [f"# {campaign.format}-truth v1", f"# t_ms {column}"]
    return lines + format_rows([(np.rint(t_ms).astype(np.int64) + clock_ms, 0), (s, decimals)])


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
