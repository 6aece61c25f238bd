"""Simulate one run of the Newcom++-like campaign and write its raw logs.

Writes exactly the files of shared/spec/raw-formats.md (uwb.log, zigbee.log, imu.log,
truth.log) plus meta.yaml; nothing else (no hidden true ranges). A scenario with the override
`uwb_tdoa: true` also writes `tdoa.csv` (generic format: one-way UWB TDOA with synchronised
anchors, sim.tdoa; settings in radio.uwb.tdoa). A 3-D scenario (`tag_height_m`,
`anchor_heights_m`: Campaign.for_scenario) ranges in 3-D; its truth.log stays the arc length
(the ingest reads the height from the same profile) and its imu.log the planar cart's. Byte-for-byte
deterministic for a given campaign file, scenario and seed sequence.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from wsnloc.campaign import Campaign
from wsnloc.sim import link_budget
from wsnloc.sim import rss as rss_model
from wsnloc.sim import trajectory as motion
from wsnloc.sim import uwb_channel
from wsnloc.sim.imu import noise_model_of
from wsnloc.sim.tdoa import tdoa_text
from wsnloc.sim.logs import imu_text, lines_text, positions as _positions, truth_text, with_heights, write_run
from wsnloc.sim.seeding import model_rng


# Paper B's simulation: "an ideal time of arrival (TOA)-based ranging where the only noisy
# impairment is due to the channel model randomness". These impairments are switched off.
IMPAIRMENTS_BESIDES_CHANNEL = {"timing_noise_ns": 0.0, "excess_path_per_wall_m": 0.0, "fault_rate": 0.0,
                               "twr_reply_time_us": 0.0}


def uwb_settings(campaign: Campaign, overrides: dict) -> dict:
    """radio.uwb of the campaign, with timing noise, wall excess path, faults and the
    two-way-ranging clock-offset bias set to 0 when the scenario's `overrides` say
    `uwb_channel_only: true`."""
    spec = dict(campaign.section("radio", "uwb"))
    if overrides.get("uwb_channel_only", False):
        spec.update(IMPAIRMENTS_BESIDES_CHANNEL)
    return spec


def twr_clock_bias_m(spec: dict, rng: np.random.Generator, n_anchors: int, c: float) -> np.ndarray:
    """Constant range bias (m) of single-sided two-way ranging with each anchor, from the
    crystal offsets of tag and anchor: the tag's estimate (T_round - T_reply) / 2 with the
    reply timed by the anchor's clock gives

        bias_j = c * T_reply * (e_tag - e_j) / 2,   e ~ U(-twr_clock_ppm, +twr_clock_ppm) * 1e-6,

    one offset per device and run (T_reply = twr_reply_time_us; 0, the default, gives no bias).
    """
    ppm = spec.get("twr_clock_ppm", 0.0) * 1e-6
    offsets = rng.uniform(-ppm, ppm, n_anchors + 1)          # [tag, anchor 1, ..., anchor n]
    return c * spec.get("twr_reply_time_us", 0.0) * 1e-6 * (offsets[0] - offsets[1:]) / 2


def ranging_rounds_ms(spec: dict, n_anchors: int, duration_s: float) -> np.ndarray:
    """Nominal start of every UWB ranging round (ms after the trajectory's start): one each
    `ranging_period_ms` from one period on, while the round's n_anchors rangings
    (`anchor_spacing_ms` apart) end inside the run of duration_s (s). _uwb_lines jitters each
    start by up to +-period_jitter_ms."""
    period = spec["ranging_period_ms"]
    return np.arange(period, duration_s * 1000 - n_anchors * spec["anchor_spacing_ms"], period)


def _uwb_lines(campaign: Campaign, spec: dict, traj, rng_time, rng_channel, rng_fault, rng_clock, rng_shadow,
               detector: str, clock_ms: int) -> list[str]:
    """`uwb.log`: one two-way time of flight per (round, anchor) whose link closes, in time order.

    Link budget (sim.link_budget): P_rx from the CM3 (no wall) / CM4 (walls) path loss and a
    shadowing field correlated along the path (one per anchor, Gudmundson, decorrelation
    `shadowing_decorrelation_m`, drawn from `rng_shadow`); the link exists when P_rx reaches
    `sensitivity_dbm`. Its channel realisation (one per anchor and `small_scale_coherence_m` of
    path travelled: small-scale fading does not change while the cart stands still) carries P_rx,
    the direct path loses
    `direct_path_wall_loss_db` per wall, and the detector reads it against the noise-referenced
    threshold (uwb_channel.detected_delays_ns); a link whose taps all stay below it gives no
    range. tw_toa_ps = round(2 (d + n_walls * excess_path_per_wall + c * (delay_detected + noise)
    + bias_anchor) / c * 1e12), bias_anchor the anchor's two-way-ranging clock-offset bias
    (twr_clock_bias_m); a `fault_rate` share of the links carries a non-zero status and a random
    value instead.
    """
    c = campaign.spec["speed_of_light_mps"]
    anchors = campaign.anchors_of("uwb")
    jitter = spec["period_jitter_ms"]
    rounds = ranging_rounds_ms(spec, len(anchors), traj.duration)
    round_ms = rounds + rng_time.uniform(-jitter, jitter, len(rounds))
    times_ms = np.round(round_ms[:, None] + np.arange(len(anchors))[None, :] * spec["anchor_spacing_ms"])
    state = _positions(campaign, traj, times_ms.ravel() / 1000.0)
    pos = state["xy"].reshape(len(rounds), len(anchors), 2)
    walls = np.column_stack([campaign.walls_between(pos[:, j], a) for j, a in
                             enumerate(anchors[["x", "y"]].to_numpy(float))])
    dist = with_heights(np.hypot(pos[..., 0] - anchors["x"].to_numpy()[None, :],
                                 pos[..., 1] - anchors["y"].to_numpy()[None, :]),
                        state["tag_z"].reshape(len(rounds), len(anchors)), anchors["z"].to_numpy(float)[None, :])
    # the shadowing field at the round's path position (the anchors of a round are ranged within
    # len(anchors) * anchor_spacing_ms, a few cm of travel, far below the decorrelation distance)
    arc = state["s"].reshape(len(rounds), len(anchors))[:, 0]
    shadow = rss_model.correlated_shadowing(arc, len(anchors), 1.0, spec["shadowing_decorrelation_m"],
                                            rng_shadow)
    power_dbm = link_budget.received_power_dbm(spec, dist, walls > 0, shadow)
    linked = power_dbm >= spec["sensitivity_dbm"]
    k, j = np.nonzero(linked)                        # row-major: time order within the run
    t_ms = times_ms[k, j].astype(np.int64) + clock_ms
    n_walls, d = walls[k, j], dist[k, j]

    faulty = rng_fault.random(len(k)) < spec["fault_rate"]
    status = np.zeros(len(k), dtype=np.int64)
    status[faulty] = rng_fault.choice(spec["fault_status_codes"], faulty.sum())
    value = np.zeros(len(k), dtype=np.int64)
    value[faulty] = rng_fault.integers(0, 200_000, faulty.sum())

    received_mw = 10 ** (power_dbm[k, j] / 10)
    direct_gain = 10 ** (-n_walls * spec["direct_path_wall_loss_db"] / 10)
    noise_threshold_mw = 10 ** (link_budget.first_path_threshold_dbm(spec) / 10)
    # one channel realisation per (anchor, small-scale cell of the path): a cart standing still
    # sees the same impulse response, hence the same leading-edge error, at every ranging
    cell = np.floor(arc / spec["small_scale_coherence_m"]).astype(np.int64)[k] * len(anchors) + j
    delay_ns = np.zeros(len(k))
    for name, of_model in (("CM3", ~faulty & (n_walls == 0)), ("CM4", ~faulty & (n_walls > 0))):
        links = np.flatnonzero(of_model)
        _, first, again = np.unique(cell[links], return_index=True, return_inverse=True)
        drawn = links[np.sort(first)]                # each realisation at its first ranging, in time order
        order = np.argsort(np.argsort(first))        # unique key -> its slot among `drawn`
        delays = uwb_channel.detected_delays_ns(
            spec["channel_models"][name], rng_channel, len(drawn), spec["cir_tap_ns"], detector,
            spec["leading_edge_threshold_db"], received_mw[drawn], direct_gain[drawn], noise_threshold_mw)
        delay_ns[links] = delays[order[again.ravel()]]
    delay_ns += rng_channel.normal(0.0, spec["timing_noise_ns"], len(k))
    range_m = d + n_walls * spec["excess_path_per_wall_m"] + c * delay_ns * 1e-9 \
        + twr_clock_bias_m(spec, rng_clock, len(anchors), c)[j]
    measured = ~faulty & np.isfinite(range_m)
    value[measured] = np.round(2.0 * range_m[measured] / c * 1e12).astype(np.int64)
    keep = faulty | measured                         # no leading edge above the threshold: no ranging

    ids = anchors["anchor_id"].to_numpy()[j[keep]]
    return ["# newcom-uwb v1", "# t_ms anchor tw_toa_ps status"] + [
        f"{t} {a} {v} {s}" for t, a, v, s in zip(t_ms[keep].tolist(), ids.tolist(), value[keep].tolist(),
                                                  status[keep].tolist())]


def _zigbee_lines(campaign: Campaign, traj, rng, clock_ms: int) -> list[str]:
    spec = campaign.section("radio", "zigbee")
    anchors = campaign.anchors_of("zigbee")
    times_ms = np.arange(spec["broadcast_period_ms"], traj.duration * 1000, spec["broadcast_period_ms"])
    state = _positions(campaign, traj, times_ms / 1000.0)
    xy = state["xy"]
    axy = anchors[["x", "y"]].to_numpy(float)
    dist = with_heights(np.hypot(xy[:, None, 0] - axy[None, :, 0], xy[:, None, 1] - axy[None, :, 1]),
                        state["tag_z"][:, None], anchors["z"].to_numpy(float)[None, :])
    walls = np.column_stack([campaign.walls_between(xy, a) for a in axy])
    shadow = rss_model.correlated_shadowing(state["s"], len(anchors), spec["shadowing_sigma_db"],
                                            spec["shadowing_decorrelation_m"], rng)
    power = rss_model.mean_rss_dbm(dist, walls, spec["p0_dbm"], spec["d0_m"],
                                   spec["path_loss_exponent"], spec["wall_loss_db"]) \
        + shadow + rng.normal(0.0, spec["fast_fading_sigma_db"], dist.shape)
    rssi = np.round(power).astype(int)
    heard = (rssi >= spec["sensitivity_dbm"]) & (rng.random(dist.shape) >= spec["reply_loss"])
    return ["# newcom-zigbee v1", "# t_ms seq n anchor:rssi_dbm ..."] + _broadcast_lines(
        times_ms, heard, rssi, anchors["anchor_id"].tolist(), clock_ms)


def _pair_texts(anchor: np.ndarray, rssi: np.ndarray, ids: list[str]) -> list[str]:
    """'<id>:<rssi>' of each (anchor index, integer RSSI in dBm) pair, each distinct pair
    formatted once (a run repeats a few hundred distinct pairs tens of thousands of times):
    pair code = anchor * span + (rssi - min rssi), its text looked up in a table over all codes
    (a few thousand entries, no sort)."""
    if len(rssi) == 0:
        return []
    low = int(rssi.min())
    span = int(rssi.max()) - low + 1
    codes = anchor * span + (rssi - low)
    table = np.empty(len(ids) * span, dtype=object)
    present = np.zeros(len(table), dtype=bool)
    present[codes] = True
    distinct = np.flatnonzero(present)
    table[distinct] = [f"{ids[code // span]}:{code % span + low}" for code in distinct.tolist()]
    return table[codes].tolist()


def _broadcast_lines(times_ms: np.ndarray, heard: np.ndarray, rssi: np.ndarray, ids: list[str],
                     clock_ms: int) -> list[str]:
    """`zigbee.log` data lines 't_ms seq n id:rssi ...', one per broadcast heard by at least
    one anchor (none heard: a gap in seq), pairs in anchor order; times_ms (N,) broadcast
    times, heard and rssi (N, anchors), t_ms = int(time) + clock_ms, seq = (b + 1) mod 256."""
    k, j = np.nonzero(heard)                                  # row-major: per broadcast, anchor order
    pairs = _pair_texts(j, rssi[k, j], ids)
    counts = heard.sum(axis=1)
    ends = np.cumsum(counts)
    rows = np.flatnonzero(counts)
    return [f"{t} {(b + 1) % 256} {n} " + " ".join(pairs[end - n:end]) for b, t, n, end in zip(
        rows.tolist(), (times_ms[rows].astype(np.int64) + clock_ms).tolist(), counts[rows].tolist(),
        ends[rows].tolist())]


def simulate_run(campaign: Campaign, scenario: str, seeds: np.random.SeedSequence, out_dir: Path,
                 *, detector: str | None = None, imu_noise: str | None = None,
                 meta: dict | None = None) -> Path:
    """Simulate `scenario` and write its raw logs into `out_dir` (created if needed).

    detector / imu_noise override the campaign's defaults (radio.uwb.detector,
    imu.noise_model); the scenario may also set them under `overrides`.
    """
    scenario_spec = campaign.section("scenarios", scenario)
    campaign = campaign.for_scenario(scenario)       # a 3-D scenario's height profile and anchor heights
    overrides = scenario_spec.get("overrides", {})
    detector = detector or overrides.get("uwb_detector") or campaign.section("radio", "uwb")["detector"]
    imu_noise = imu_noise or noise_model_of(campaign, scenario)
    clock_ms = int(campaign.spec.get("clock_start_ms", 0))

    traj = motion.for_scenario(scenario_spec, campaign.path.length, model_rng(seeds, "motion"))
    files = {
        "uwb.log": lines_text(_uwb_lines(campaign, uwb_settings(campaign, overrides), traj,
                                         model_rng(seeds, "uwb-timing"), model_rng(seeds, "uwb-channel"),
                                         model_rng(seeds, "uwb-faults"), model_rng(seeds, "uwb-clock"),
                                         model_rng(seeds, "uwb-shadowing"), detector, clock_ms)),
        "zigbee.log": lines_text(_zigbee_lines(campaign, traj, model_rng(seeds, "zigbee"), clock_ms)),
        "imu.log": imu_text(campaign, traj, model_rng(seeds, "imu"), imu_noise, clock_ms),
        "truth.log": truth_text(campaign, traj, clock_ms, "rail_m"),
    }
    if overrides.get("uwb_tdoa", False):
        files["tdoa.csv"] = tdoa_text(campaign, uwb_settings(campaign, overrides), traj,
                                      *(model_rng(seeds, f"tdoa-{m}") for m in ("timing", "channel", "clock", "shadow")),
                                      detector, clock_ms)
    return write_run(out_dir, files, campaign, scenario, seeds,
                     {"uwb_detector": detector, "imu_noise_model": imu_noise, **(meta or {})})
