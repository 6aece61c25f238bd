"""One-way UWB TDOA with synchronised anchors: the simulated `tdoa.csv` of a run (generic format).

The tag blinks every `blink_period_ms` (jitter U(+-period_jitter_ms) as the ranging rounds);
each anchor whose link to the tag closes (the two-way ranging's link budget, sim.link_budget:
P_rx with a shadowing field correlated along the path reaches sensitivity_dbm, and the
detector finds a leading edge above its threshold) timestamps the arrival on its own clock. The
anchors' clocks run free (offset and a frequency error e_j ~ U(+-twr_clock_ppm), IEEE
802.15.4a's crystal tolerance) and are synchronised to the reference anchor's clock by its
sync packets every `sync_period_ms` (the usual wireless clock synchronisation of UWB RTLS):
at sync k each anchor timestamps the packet, whose known flight time it removes, with the
same leading-edge jitter as any arrival (timing_noise_ns). Its offset estimate then errs by
that jitter n_k, and its frequency estimate, from two successive syncs, by
(n_k - n_{k-1}) / sync_period; between syncs the residual clock error is

    eps_j(t) = n_k + (n_k - n_{k-1}) / sync_period * (t - s_k)       (s, s_k the last sync),

so the free-running offset and drift cancel and what stays is set by the timing jitter. The
arrival time at anchor j of a blink at t:

    T_j = t + (d_j + n_walls,j * excess_path_per_wall + c (delay_j + noise_j)) / c + eps_j(t),

delay_j the detected excess delay of the link's channel model (CM3 LOS, CM4 NLOS, one way;
its realisation carries P_rx, the direct path loses direct_path_wall_loss_db per wall),
noise_j ~ N(0, timing_noise_ns). One row per linked anchor j other than the reference and
blink whose reference is linked: tdoa_m = c (T_j - T_ref) (eps_ref = 0: the reference is the
time master), t = the blink time on the logger clock. d_j is 3-D when anchors have z (sim.logs.with_heights).
"""

from __future__ import annotations

import numpy as np

from wsnloc.campaign import Campaign
from wsnloc.sim import link_budget, uwb_channel
from wsnloc.sim import rss as rss_model
from wsnloc.sim.logs import positions as _positions, with_heights


def _sync_errors(n_anchors: int, times_s: np.ndarray, sync_period_s: float, jitter_s: float,
                 rng: np.random.Generator) -> np.ndarray:
    """(len(times), n_anchors) residual clock error eps_j(t) in s after synchronisation (module docstring)."""
    n_syncs = int(np.ceil((times_s.max(initial=0.0) + sync_period_s) / sync_period_s)) + 2
    noise = rng.normal(0.0, jitter_s, (n_syncs, n_anchors))
    k = np.clip(np.floor(times_s / sync_period_s).astype(int), 1, n_syncs - 1)
    since = times_s - k * sync_period_s
    return noise[k] + (noise[k] - noise[k - 1]) / sync_period_s * since[:, None]


def tdoa_text(campaign: Campaign, uwb: dict, traj, rng_time: np.random.Generator, rng_channel: np.random.Generator,
              rng_clock: np.random.Generator, rng_shadow: np.random.Generator, detector: str, clock_ms: int) -> str:
    """The run's `tdoa.csv` text (module docstring); `uwb`: the campaign's radio.uwb (with the
    scenario's overrides), its `tdoa` section the TDOA settings."""
    spec = uwb["tdoa"]
    c = campaign.spec["speed_of_light_mps"]
    anchors = campaign.anchors_of("uwb")
    ids = anchors["anchor_id"].to_numpy(dtype=object)
    reference = spec["reference_anchor"]
    if reference not in set(ids):
        raise ValueError(f"{campaign.source}: radio.uwb.tdoa.reference_anchor {reference!r} is not a uwb anchor")
    ref = int(np.flatnonzero(ids == reference)[0])
    period = spec["blink_period_ms"]
    blinks_ms = np.arange(period, traj.duration * 1000, period)
    blinks_ms = blinks_ms + rng_time.uniform(-uwb["period_jitter_ms"], uwb["period_jitter_ms"], len(blinks_ms))
    t = blinks_ms / 1000.0
    state = _positions(campaign, traj, t)
    xy = state["xy"]
    axy = anchors[["x", "y"]].to_numpy(float)
    walls = np.column_stack([campaign.walls_between(xy, a) for a in axy])
    dist = np.hypot(xy[:, None, 0] - axy[None, :, 0], xy[:, None, 1] - axy[None, :, 1])
    dist = with_heights(dist, state["tag_z"][:, None], anchors["z"].to_numpy(float)[None, :])
    shadow = rss_model.correlated_shadowing(state["s"], len(anchors), 1.0, uwb["shadowing_decorrelation_m"],
                                            rng_shadow)
    power_dbm = link_budget.received_power_dbm(uwb, dist, walls > 0, shadow)
    linked = power_dbm >= uwb["sensitivity_dbm"]
    received_mw = 10 ** (power_dbm / 10)
    direct_gain = 10 ** (-walls * uwb["direct_path_wall_loss_db"] / 10)
    noise_threshold_mw = 10 ** (link_budget.first_path_threshold_dbm(uwb) / 10)
    delay_ns = np.zeros(dist.shape)
    for name, of_model in (("CM3", linked & (walls == 0)), ("CM4", linked & (walls > 0))):
        delay_ns[of_model] = uwb_channel.detected_delays_ns(
            uwb["channel_models"][name], rng_channel, int(of_model.sum()), uwb["cir_tap_ns"], detector,
            uwb["leading_edge_threshold_db"], received_mw[of_model], direct_gain[of_model], noise_threshold_mw)
    delay_ns += rng_channel.normal(0.0, uwb["timing_noise_ns"], dist.shape)
    linked &= np.isfinite(delay_ns)                  # no leading edge above the threshold: no timestamp
    sync = _sync_errors(len(anchors), t, spec["sync_period_ms"] / 1000.0, uwb["timing_noise_ns"] * 1e-9, rng_clock)
    sync[:, ref] = 0.0
    path_m = dist + walls * uwb["excess_path_per_wall_m"] + c * (delay_ns * 1e-9 + sync)
    k, j = np.nonzero(linked & linked[:, [ref]] & (np.arange(len(anchors)) != ref)[None, :])
    tdoa = path_m[k, j] - path_m[k, ref]
    stamps = (np.round(blinks_ms[k]).astype(np.int64) + clock_ms) / 1000.0
    rows = [f"{s:.3f},{a},{reference},{v:.4f}" for s, a, v in zip(stamps.tolist(), ids[j].tolist(), tdoa.tolist())]
    return "\n".join(["t,anchor_id,ref_anchor_id,tdoa_m", *rows]) + "\n"
