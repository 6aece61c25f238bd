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
    """Path state (s, v, a) and pose (x, y, heading, curvature; z on a path with a height
    profile) at the given times; `tag_z` the tag's height (m): z, else the campaign's fixed
    tag_height_m, else 0 (as the estimators take it, RunData)."""
    state = traj.at(times_s)
    pose = campaign.path.evaluate(state["s"])
    tag_z = pose["z"] if "z" in pose else np.full(len(pose["x"]), float(campaign.tag_height_m or 0.0))
    return {**state, **pose, "xy": np.column_stack([pose["x"], pose["y"]]), "tag_z": tag_z}


def with_heights(horizontal: np.ndarray, tag_z: np.ndarray, anchor_z: np.ndarray) -> np.ndarray:
    """Tag-anchor distances (m) from the horizontal ones (..., anchors): sqrt(d^2 + (z_anchor -
    z_tag)^2) for anchors with a height (finite z), d for the others; `tag_z` broadcasts
    against `horizontal`. Unchanged (the same array) when no anchor has a height."""
    if not np.isfinite(anchor_z).any():
        return horizontal
    dz = np.where(np.isfinite(anchor_z), anchor_z - tag_z, 0.0)
    return np.sqrt(horizontal**2 + dz**2)


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


def _magnitudes(values: np.ndarray, decimals: int) -> tuple[np.ndarray, np.ndarray, int]:
    """(|x| as int64, sign, decimals) of a column: |x| itself for an integer array (decimals
    becomes 0, sign x < 0), round(|x| 10^decimals) for a float array (sign: the sign bit, as
    Python writes '-0.000')."""
    if np.issubdtype(values.dtype, np.integer):
        magnitude = np.abs(values.astype(np.int64))
        if magnitude.size and magnitude.min() < 0:
            raise ValueError("the int64 minimum has no int64 magnitude")
        return magnitude, values < 0, 0
    return _scaled_integers(values, decimals), np.signbit(values), decimals


def _offset_code(character: str) -> int:
    """The byte of an ASCII character minus ord('0'), modulo 256 (format_text's matrix codes)."""
    return (ord(character) - ord("0")) % 256


def format_text(columns: list[tuple[np.ndarray, int]]) -> str:
    """Text of lines of space-separated numbers, each line ending in '\\n', column = (values,
    decimals): byte for byte what '%d' (integer array) or '%.{decimals}f' (float array) writes.

    Each row is laid out in a fixed-width character matrix (sign, digits of the magnitude
    m = sum_i d_i 10^i written from d_0 leftwards, '.' before the last `decimals` digits,
    separator); a leading zero d_i (i > decimals and m < 10^i) and an absent sign are masked,
    and the kept characters, read row by row, are the text. The matrix holds each byte minus
    ord('0') (mod 256), so a digit is written as its value d_i = r - 10 (r // 10), r = m // 10^i, and
    ord('0') is added once to the kept bytes.
    """
    fields = [_magnitudes(np.asarray(values), decimals) for values, decimals in columns]
    n = len(fields[0][0])
    widths = [max(len(str(int(magnitude.max()))) if n else 1, decimals + 1) for magnitude, _, decimals in fields]
    chars = np.empty((n, sum(w + 2 + (d > 0) for w, (_, _, d) in zip(widths, fields))), dtype=np.uint8)
    kept = np.ones(chars.shape, dtype=bool)
    column = 0
    for index, ((magnitude, negative, decimals), width) in enumerate(zip(fields, widths)):
        chars[:, column], kept[:, column] = _offset_code("-"), negative
        separator = column + 1 + width + (decimals > 0)
        rest = magnitude.astype(np.uint32) if width < 10 else magnitude     # m < 10^9 < 2^32: faster division
        for i in range(width):                      # digit d_i of m, i = 0 the last one written
            at = separator - 1 - i - (0 < decimals <= i)
            quotient = rest // 10
            chars[:, at] = rest - 10 * quotient
            if i > decimals:
                kept[:, at] = rest > 0
            rest = quotient
        if decimals:
            chars[:, separator - 1 - decimals] = _offset_code(".")
        chars[:, separator] = _offset_code("\n" if index == len(fields) - 1 else " ")
        column = separator + 1
    text = np.compress(kept.ravel(), chars.ravel())
    text += ord("0")
    return str(text, "ascii")                       # decoded from the array's buffer, no bytes copy


def lines_text(lines: list[str]) -> str:
    """A log file's text from its lines: each line followed by '\\n'."""
    return "\n".join(lines) + "\n"


def _sorted(values: np.ndarray) -> np.ndarray:
    """np.sort(values) for finite floats without -0.0, skipping the sort when they are already in
    order (a jitter much smaller than the sampling period almost never reorders samples): equal
    finite values other than +-0 have equal bits, so both give the same array."""
    return values if np.all(values[1:] >= values[:-1]) else np.sort(values)


def imu_text(campaign: Campaign, traj: Trajectory, rng, noise_model: str, clock_ms: int) -> str:
    """`imu.log`: sensor-clock time (3 decimals, jittered, some samples dropped) and raw counts."""
    spec = dict(campaign.section("imu"), noise_model=noise_model)
    g = campaign.spec["gravity_mps2"]
    period_ms = 1000.0 / spec["rate_hz"]
    nominal = np.arange(0.0, traj.duration * 1000, period_ms)
    t_ms = nominal + rng.normal(0.0, spec["timestamp_jitter_ms"], len(nominal))
    kept = rng.random(len(t_ms)) >= spec["drop_rate"]
    t_ms = _sorted(t_ms[kept])
    state = positions(campaign, traj, t_ms / 1000.0)
    force, yaw_rate = imu_model.body_motion(state["v"], state["a"], state["curvature"], g)
    accel, gyro = imu_model.sensor_readings(t_ms / 1000.0, force, yaw_rate, state["v"], spec, g, rng,
                                            state["s"])
    acc_counts, gyro_counts = imu_model.to_counts(accel, gyro, spec, g)
    header = [f"# {campaign.format}-imu v1",
              f"# accel_lsb_per_g={spec['accel_lsb_per_g']:g} gyro_lsb_per_dps={spec['gyro_lsb_per_dps']:g}",
              "# t_ms ax ay az gz"]
    acc_counts = np.asarray(acc_counts)
    return lines_text(header) + format_text([(t_ms + clock_ms, 3), *((column, 0) for column in acc_counts.T),
                                             (np.asarray(gyro_counts), 0)])


def truth_text(campaign: Campaign, traj: Trajectory, clock_ms: int, column: str) -> str:
    """`truth.log`: position along the path (`rail_m` or `path_m`) at the truth rate."""
    spec = campaign.section("truth")
    period_ms = 1000.0 / spec["rate_hz"]
    t_ms = np.arange(0.0, traj.duration * 1000 + 1e-9, period_ms)
    s = np.round(traj.at(t_ms / 1000.0)["s"] / spec["resolution_m"]) * spec["resolution_m"]
    decimals = max(0, int(round(-np.log10(spec["resolution_m"]))))
    header = [f"# {campaign.format}-truth v1", f"# t_ms {column}"]
    return lines_text(header) + format_text([(np.rint(t_ms).astype(np.int64) + clock_ms, 0), (s, decimals)])


def write_run(out_dir: Path, files: dict[str, str], campaign: Campaign, scenario: str,
              seeds: np.random.SeedSequence, meta: dict) -> Path:
    """Write the log files (name: text) and meta.yaml (no wall-clock date, so reruns are byte-identical)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (out_dir / name).write_text(text, encoding="ascii")
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
