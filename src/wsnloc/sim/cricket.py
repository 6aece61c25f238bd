"""Simulate one run of the Cricket campaign (paper C) and write its raw logs.

Each beacon sends RF + ultrasound at random intervals uniform in [668, 1332] ms (Cricket v2
firmware); a share of messages is lost to collisions. The listener measures the
ultrasound flight time:  DR = d_measured / c_sound  (us), with
  c_sound = 331.3 + 0.606 T  (m/s, T in deg C),
  d_measured = ||p - b_true|| + N(0, sigma) (+ U(0.2, 1.5) m for a reflection);
beyond the ultrasound range only the RF part arrives (a line without DB/DR).
True beacon positions are the nominal ones plus the hand-measurement error; the
estimators only know the nominal positions from the campaign file.
A small share of lines is damaged on the serial link (cut short, or run into the next
line), as in real captures. The cart's controller logs its wheel odometry from two wheel
encoders (odometry_text). Writes listener.log (host ms + TAB + Cricket v2 line), imu.log,
truth.log, odometry.log, meta.yaml.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wsnloc.campaign import Campaign
from wsnloc.sim import trajectory as motion
from wsnloc.sim.imu import noise_model_of
from wsnloc.sim.logs import format_text, imu_text, lines_text, positions, truth_text, write_run
from wsnloc.sim.seeding import model_rng


def speed_of_sound(temperature_c: float) -> float:
    """m/s, linear approximation around 0 deg C: 331.3 + 0.606 T."""
    return 331.3 + 0.606 * temperature_c


def _serial_damage(lines: list[str], rate: float, rng) -> list[str]:
    """Lines lost on the serial link: a share is cut short or runs into the next line."""
    out, k = [], 0
    while k < len(lines):
        line = lines[k]
        if rng.random() < rate:
            if rng.random() < 0.5 or k + 1 == len(lines):
                out.append(line[: int(rng.integers(len(line) // 3, len(line) - 1))])   # cut short
            else:
                out.append(line + lines[k + 1].split("\t", 1)[1])                   # newline lost
                k += 1
        else:
            out.append(line)
        k += 1
    return out


def _listener_lines(campaign: Campaign, traj, rng_beacons, rng_timing, rng_range, clock_ms: int) -> list[str]:
    spec = campaign.section("radio", "cricket")
    anchors = campaign.anchors_of("cricket")
    nominal = anchors[["x", "y"]].to_numpy(float)
    true_xy = nominal + rng_beacons.normal(0.0, spec["beacon_position_sigma_m"], nominal.shape)
    c = speed_of_sound(spec["temperature_c"])
    low, high = spec["interval_ms"]
    duration_ms = traj.duration * 1000.0
    events = []
    for j in range(len(anchors)):
        t = rng_timing.uniform(0.0, high)
        while t < duration_ms:
            if rng_timing.random() >= spec["collision_loss"]:
                events.append((t, j))
            t += rng_timing.uniform(low, high)
    events.sort()
    times = np.array([e[0] for e in events])
    which = np.array([e[1] for e in events], dtype=int)
    xy = positions(campaign, traj, times / 1000.0)["xy"]
    distance = np.hypot(*(xy - true_xy[which]).T)
    measured = distance + rng_range.normal(0.0, spec["range_noise_m"], len(events))
    reflected = rng_range.random(len(events)) < spec["reflection_rate"]
    measured += reflected * rng_range.uniform(*spec["reflection_excess_m"], len(events))
    listener_boot_ms = int(rng_timing.integers(1_000, 60_000))        # listener clock offset
    heads = [f"VR=2.0,ID={b},SP={s}" for b, s in zip(anchors["beacon_id"].tolist(), anchors["space_id"].tolist())]
    hosts = (np.trunc(times).astype(np.int64) + clock_ms).tolist()
    ultrasound = (distance <= spec["max_ultrasound_range_m"]).tolist()
    db, dr = np.rint(measured * 100).astype(np.int64).tolist(), np.rint(measured / c * 1e6).astype(np.int64).tolist()
    lines = []
    for host, j, heard, cm, us in zip(hosts, which.tolist(), ultrasound, db, dr):
        ranged = f",DB={cm},DR={us}" if heard else ""
        lines.append(f"{host}\t{heads[j]}{ranged},TS={host + listener_boot_ms}")
    header = [f"# {campaign.format}-listener v1", "# host_ms<TAB>Cricket v2 line"]
    return header + _serial_damage(lines, spec["serial_damage_rate"], rng_range)


def odometry_text(campaign: Campaign, traj, rng, clock_ms: int) -> str:
    """`odometry.log`: `t_ms v_mmps yaw_mradps` at the campaign's odometry rate, as the cart's
    controller computes them from its two wheel encoders (campaign section `odometry`).

    Wheel travel along the path: s_l,r = s -/+ (b / 2) (theta - theta_0) (s the path position,
    theta the unwrapped heading, b the wheelbase). A wheel of true diameter D (1 + e_w),
    e_w ~ N(0, diameter_sigma) per run and wheel, turns s_w / (pi D (1 + e_w)) revolutions: its
    encoder counts floor(counts_per_rev s_w / (pi D (1 + e_w))). Per sample period dt the
    controller reads v_w = dcounts pi D / counts_per_rev / dt with the NOMINAL D, then
    v = (v_l + v_r) / 2 (m/s) and yaw rate w = (v_r - v_l) / b (rad/s), written in mm/s and mrad/s.
    """
    spec = campaign.section("odometry")
    period_ms = 1000.0 / spec["rate_hz"]
    t_ms = np.arange(0.0, traj.duration * 1000 + 1e-9, period_ms)
    pose = positions(campaign, traj, t_ms / 1000.0)
    turned = np.unwrap(pose["heading"]) - pose["heading"][0]
    half = spec["wheelbase_m"] / 2.0
    per_count = np.pi * spec["wheel_diameter_m"] / spec["encoder_counts_per_rev"]      # m per count, nominal
    scale = 1.0 + rng.normal(0.0, spec["diameter_sigma"], 2)                           # true / nominal D
    counts = [np.floor((pose["s"] + sign * half * turned) / (per_count * k)) for sign, k in zip((-1.0, 1.0), scale)]
    left, right = (np.diff(c) * per_count / (np.diff(t_ms) / 1000.0) for c in counts)
    v, w = (left + right) / 2.0, (right - left) / spec["wheelbase_m"]
    header = [f"# {campaign.format}-odometry v1", "# t_ms v_mmps yaw_mradps"]
    return lines_text(header) + format_text([(np.rint(t_ms[1:]).astype(np.int64) + clock_ms, 0),
                                             (np.rint(v * 1000.0).astype(np.int64), 0),
                                             (np.rint(w * 1000.0).astype(np.int64), 0)])


def simulate_run(campaign: Campaign, scenario: str, seeds: np.random.SeedSequence, out_dir: Path,
                 *, imu_noise: str | None = None, meta: dict | None = None, **_ignored) -> Path:
    """Simulate `scenario` (e.g. speed_40) and write its raw logs into `out_dir`."""
    scenario_spec = campaign.section("scenarios", scenario)
    imu_noise = imu_noise or noise_model_of(campaign, scenario)
    clock_ms = int(campaign.spec.get("clock_start_ms", 0))
    traj = motion.for_scenario(scenario_spec, campaign.path.length, model_rng(seeds, "motion"))
    files = {
        "listener.log": lines_text(_listener_lines(campaign, traj, model_rng(seeds, "beacons"),
                                                   model_rng(seeds, "timing"), model_rng(seeds, "ranging"), clock_ms)),
        "imu.log": imu_text(campaign, traj, model_rng(seeds, "imu"), imu_noise, clock_ms),
        "truth.log": truth_text(campaign, traj, clock_ms, "path_m"),
        "odometry.log": odometry_text(campaign, traj, model_rng(seeds, "odometry"), clock_ms),
    }
    return write_run(out_dir, files, campaign, scenario, seeds, {"imu_noise_model": imu_noise, **(meta or {})})
