"""Campaign simulator: determinism, what it writes, and each physical sub-model."""

import hashlib

import numpy as np
import yaml
import pytest

from wsnloc.io.newcom import ingest_run
from wsnloc.sim import rss, trajectory, uwb_channel
from wsnloc.sim.imu import body_motion, to_counts
from wsnloc.sim.newcom import simulate_run
from wsnloc.sim.seeding import model_rng, run_seed_sequence


def _digests(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def test_same_seed_gives_byte_identical_logs(campaign, simulated_run, tmp_path):
    again = simulate_run(campaign, "constant", run_seed_sequence(7, "newcom", "constant", 1), tmp_path / "again")
    assert _digests(again) == _digests(simulated_run)


def test_other_seed_gives_other_logs(campaign, simulated_run, tmp_path):
    other = simulate_run(campaign, "constant", run_seed_sequence(7, "newcom", "constant", 2), tmp_path / "other")
    a, b = _digests(other), _digests(simulated_run)
    assert a["uwb.log"] != b["uwb.log"] and a["imu.log"] != b["imu.log"]
    assert a["truth.log"] == b["truth.log"]      # the constant-speed motion is not random


def test_writes_only_the_raw_files(simulated_run):
    assert sorted(p.name for p in simulated_run.iterdir()) == ["imu.log", "meta.yaml", "truth.log", "uwb.log", "zigbee.log"]
    header = (simulated_run / "uwb.log").read_text().splitlines()[:2]
    assert header == ["# newcom-uwb v1", "# t_ms anchor tw_toa_ps status"]


def test_constant_profile():
    traj = trajectory.constant_speed(24.57, 5.0, 1.0, 0.30, 5.0)
    assert traj.v.max() == pytest.approx(0.30, abs=1e-9)
    assert traj.s[-1] == pytest.approx(24.57, abs=1e-6)
    assert traj.at([4.9])["s"][0] == 0.0 and traj.at([traj.duration - 4.9])["v"][0] == 0.0
    assert traj.duration == pytest.approx(5 + 1 + (24.57 - 0.3) / 0.3 + 1 + 5, abs=0.01)


def test_variable_profile_stays_in_range_and_stops_half_way():
    rng = np.random.default_rng(3)
    traj = trajectory.variable_speed(24.57, rng, 5.0, 5.0, [0.1, 0.5], 0.3, 4.0, 5.0)
    assert traj.s[-1] == pytest.approx(24.57, abs=1e-3)
    assert traj.v.max() <= 0.5 + 1e-9 and traj.v.min() >= 0.0
    moving = traj.t[(traj.t > 5.0) & (traj.t < traj.duration - 5.0)]
    halted = traj.at(moving)["v"] == 0.0
    stop_positions = traj.at(moving[halted])["s"]
    assert halted.sum() * trajectory.STEP_S == pytest.approx(4.0, abs=0.05)
    assert np.all(np.abs(stop_positions - 24.57 / 2) < 1e-3)


def _taps(model, rng, n_links, tap_ns=1.0):
    link, delays, amplitudes = uwb_channel.impulse_responses(model, rng, n_links)
    return uwb_channel.tap_powers(link, delays, amplitudes, tap_ns, n_links)


def test_first_path_is_never_later_than_strongest_path(campaign):
    spec = campaign.section("radio", "uwb")
    rng = np.random.default_rng(0)
    for name in ("CM3", "CM4"):
        taps = _taps(spec["channel_models"][name], rng, 400)
        first = uwb_channel.detect_delay_ns(taps, 1.0, "first_path", 15.0)
        strongest = uwb_channel.detect_delay_ns(taps, 1.0, "strongest_path", 15.0)
        assert first.shape == (400,) and np.all((0.0 <= first) & (first <= strongest))


def test_detectors_on_hand_made_taps():
    powers = np.array([[0.0, 0.02, 1.0, 0.5], [0.5, 0.0, 0.2, 1.0]])
    assert uwb_channel.detect_delay_ns(powers, 2.0, "strongest_path", 15.0).tolist() == [4.0, 6.0]
    # 15 dB below the peak: 0.0316 -> the 0.02 tap is below it, the 0.5 tap above
    assert uwb_channel.detect_delay_ns(powers, 2.0, "first_path", 15.0).tolist() == [4.0, 0.0]


def test_tap_powers_sum_rays_coherently_per_link():
    link = np.array([0, 0, 1, 1])
    delays = np.array([0.2, 0.7, 0.1, 2.5])
    amplitudes = np.array([1.0, -1.0, 1j, 2.0])
    powers = uwb_channel.tap_powers(link, delays, amplitudes, 1.0, 3)
    np.testing.assert_allclose(powers, [[0, 0, 0], [1, 0, 4], [0, 0, 0]])


def test_nlos_strongest_path_is_biased_by_the_diffuse_first_cluster(campaign):
    """CM4's rising first cluster delays the strongest tap by several ns; CM3's LOS ray does not."""
    spec = campaign.section("radio", "uwb")

    def median_delay(name):
        delays = uwb_channel.detected_delays_ns(spec["channel_models"][name], np.random.default_rng(1), 400, 1.0,
                                                "strongest_path", 15.0)
        return np.median(delays)

    assert median_delay("CM4") > 5.0 > median_delay("CM3")


def test_detector_names_are_checked():
    with pytest.raises(ValueError, match="unknown UWB detector"):
        uwb_channel.detect_delay_ns(np.ones((1, 3)), 1.0, "earliest", 15.0)
    with pytest.raises(ValueError, match="unknown UWB detector"):
        uwb_channel.detected_delays_ns({}, np.random.default_rng(0), 0, 1.0, "earliest", 15.0)


def _one_link_reference(model, rng):
    """The channel model drawn one link at a time, as the simulator did before the batched
    version (an independent transcription of the module docstring's equations)."""
    beta, l1, l2 = model["ray_mixture_beta"], model["ray_rate_1_per_ns"], model["ray_rate_2_per_ns"]
    diffuse = bool(model.get("diffuse_first_cluster", False))
    n_clusters = max(1, rng.poisson(model["mean_clusters"]))
    cluster_t = np.concatenate([[0.0], np.cumsum(rng.exponential(1 / model["cluster_rate_per_ns"], n_clusters - 1))])
    cluster_t = cluster_t[cluster_t < uwb_channel.CLUSTER_SPAN * model["cluster_decay_ns"]]
    delays, powers = [], []
    for index, t in enumerate(cluster_t):
        omega = 10 ** ((-10 * np.log10(np.e) * t / model["cluster_decay_ns"]
                        + rng.normal(0.0, model["cluster_sigma_db"])) / 10)
        gamma = model["first_cluster_decay_ns"] if diffuse and index == 0 else model["ray_decay_ns"]
        tau = 0.0
        for ray in range(10_000):
            if ray > 0:
                tau += rng.exponential(1 / l1) if rng.random() < beta else rng.exponential(1 / l2)
            if tau >= uwb_channel.RAY_SPAN * gamma:
                break
            if diffuse and index == 0:
                rise, chi = model["rise_ns"], model["diffuse_chi"]
                mean = omega * (1 - chi * np.exp(-tau / rise)) * np.exp(-tau / gamma) \
                    * (gamma + rise) / (gamma * (gamma + rise * (1 - chi)))
            else:
                mean = omega / (gamma * ((1 - beta) * l1 + beta * l2 + 1)) * np.exp(-tau / gamma)
            m = max(np.exp(rng.normal(model["nakagami_m0"], model["nakagami_sigma_m0"])), 0.5)
            if ray == 0 and model.get("first_ray_m") is not None:
                m = model["first_ray_m"]
            delays.append(t + tau)
            powers.append(rng.gamma(m, mean / m) * np.exp(1j * rng.uniform(0, 2 * np.pi)))
    amplitudes = np.sqrt(np.abs(powers)) * np.exp(1j * np.angle(powers))
    return np.array(delays), amplitudes


def _same_mean(a, b) -> bool:
    return abs(a.mean() - b.mean()) <= 4 * np.sqrt(a.var() / len(a) + b.var() / len(b))


@pytest.mark.parametrize("name", ["CM3", "CM4"])
def test_batched_channel_has_the_statistics_of_one_link_at_a_time(campaign, name):
    """Over 1500 links: ray count, total energy and detected first-path / strongest-path
    excess delays have the same distribution (two-sample KS, p > 0.001) and the same mean
    (difference within 4 standard errors)."""
    from scipy.stats import ks_2samp

    spec = campaign.section("radio", "uwb")
    model, tap = spec["channel_models"][name], spec["cir_tap_ns"]
    n = 1500
    rng = np.random.default_rng(11)
    reference = [_one_link_reference(model, rng) for _ in range(n)]
    ref_rays = np.array([len(d) for d, _ in reference])
    ref_energy = np.array([np.sum(np.abs(a) ** 2) for _, a in reference])
    link, delays, amplitudes = uwb_channel.impulse_responses(model, np.random.default_rng(12), n)
    rays = np.bincount(link, minlength=n)
    energy = np.bincount(link, weights=np.abs(amplitudes) ** 2, minlength=n)
    ref_taps = [uwb_channel.tap_powers(np.zeros(len(d), int), d, a, tap, 1) for d, a in reference]
    taps = uwb_channel.tap_powers(link, delays, amplitudes, tap, n)
    for detector in ("first_path", "strongest_path"):
        ref = np.concatenate([uwb_channel.detect_delay_ns(t, tap, detector, 15.0) for t in ref_taps])
        new = uwb_channel.detect_delay_ns(taps, tap, detector, 15.0)
        assert ks_2samp(ref, new).pvalue > 1e-3, detector
        assert _same_mean(ref, new), detector
    assert ks_2samp(ref_rays, rays).pvalue > 1e-3
    assert ks_2samp(ref_energy, energy).pvalue > 1e-3
    assert _same_mean(ref_energy, energy) and _same_mean(ref_rays, rays)


def test_shadowing_has_the_gudmundson_correlation():
    """Correlation between samples d apart along the path is exp(-d / d_c)."""
    arc = np.arange(0, 4000.0, 0.5)
    x = rss.correlated_shadowing(arc, 1, 4.0, 2.0, np.random.default_rng(5))[:, 0]
    assert x.std() == pytest.approx(4.0, rel=0.05)
    lag = 4                                   # 2 m
    rho = np.corrcoef(x[:-lag], x[lag:])[0, 1]
    assert rho == pytest.approx(np.exp(-1.0), abs=0.05)


def test_static_cart_shadowing_does_not_change():
    x = rss.correlated_shadowing(np.zeros(50), 3, 4.0, 2.0, np.random.default_rng(1))
    assert np.ptp(x, axis=0).max() == 0.0


def test_imu_counts_at_rest_and_clipping(campaign):
    spec, g = campaign.section("imu"), campaign.spec["gravity_mps2"]
    force, yaw = body_motion(np.zeros(2), np.zeros(2), np.zeros(2), g)
    acc, gyro = to_counts(force, yaw, spec, g)
    assert acc.tolist() == [[0, 0, 1024], [0, 0, 1024]] and gyro.tolist() == [0, 0]
    acc, _ = to_counts(np.array([[100.0, -100.0, 0.0]]), np.zeros(1), spec, g)
    assert acc.tolist() == [[2047, -2048, 0]]


def test_turn_gives_centripetal_force_and_yaw_rate():
    force, yaw = body_motion(np.array([0.3]), np.array([0.0]), np.array([1.0]), 9.81)
    assert force[0].tolist() == pytest.approx([0.0, 0.09, 9.81]) and yaw[0] == pytest.approx(0.3)


def test_fault_rate_and_ranging_period(campaign, simulated_run):
    tables, _ = ingest_run(simulated_run, campaign)
    ranges = tables["ranges"]
    assert 0.015 < (ranges["status"] != 0).mean() < 0.05            # spec: ~3%
    rounds = np.diff(np.unique(np.round(ranges.loc[ranges["anchor_id"] == "U02", "t"], 1)))
    assert np.median(rounds) == pytest.approx(0.5, abs=0.01)
    rss_t = np.unique(tables["rss"]["t"])
    assert np.median(np.diff(rss_t)) == pytest.approx(0.05, abs=1e-6)
    imu_dt = np.diff(tables["imu"]["t"])
    assert np.median(imu_dt) == pytest.approx(0.002, abs=1e-4)


def test_model_streams_are_independent():
    seq = run_seed_sequence(1, "newcom", "constant", 1)
    assert model_rng(seq, "uwb").random() != model_rng(seq, "imu").random()
    assert model_rng(seq, "uwb").random() == model_rng(seq, "uwb").random()


def test_b_simulation_ranging_is_impaired_by_the_channel_only(campaign, tmp_path):
    """Paper B: "the only noisy impairment is due to the channel model randomness"."""
    from wsnloc.sim.newcom import IMPAIRMENTS_BESIDES_CHANNEL, uwb_settings

    spec = uwb_settings(campaign, campaign.section("scenarios", "b_simulation")["overrides"])
    assert {k: spec[k] for k in IMPAIRMENTS_BESIDES_CHANNEL} == IMPAIRMENTS_BESIDES_CHANNEL
    assert uwb_settings(campaign, {})["timing_noise_ns"] > 0        # other scenarios keep them
    run = simulate_run(campaign, "b_simulation", run_seed_sequence(7, "newcom", "b_simulation", 1), tmp_path)
    tables, _ = ingest_run(run, campaign)
    ranges, truth = tables["ranges"], tables["truth"]
    assert (ranges["status"] == 0).all()                             # no faults
    # Without timing noise a detected path is never earlier than the direct one: range >= distance
    # (up to the 1 cm truth resolution and its interpolation between 25 Hz frames).
    anchors = campaign.anchors.set_index("anchor_id")
    x, y = np.interp(ranges["t"], truth["t"], truth["x"]), np.interp(ranges["t"], truth["t"], truth["y"])
    distance = np.hypot(x - anchors.loc[ranges["anchor_id"], "x"].to_numpy(),
                        y - anchors.loc[ranges["anchor_id"], "y"].to_numpy())
    assert (ranges["range_m"] - distance).min() > -0.02
    assert yaml.safe_load((run / "meta.yaml").read_text())["imu_noise_model"] == "snr"


def _without_twr_keys(campaign):
    """The campaign as before the two-way-ranging clock parameters existed."""
    import copy

    from wsnloc.campaign import Campaign

    spec = copy.deepcopy(campaign.spec)
    for key in ("twr_clock_ppm", "twr_reply_time_us"):
        del spec["radio"]["uwb"][key]
    return Campaign(campaign.name, campaign.format, spec, campaign.source)


def test_zero_twr_reply_time_leaves_the_raw_logs_identical(campaign, simulated_run, tmp_path):
    assert campaign.section("radio", "uwb")["twr_reply_time_us"] == 0.0
    before = simulate_run(_without_twr_keys(campaign), "constant", run_seed_sequence(7, "newcom", "constant", 1),
                          tmp_path / "before")
    assert _digests(before) == _digests(simulated_run)


def test_twr_clock_bias_is_one_constant_per_anchor(campaign, simulated_run, tmp_path):
    from wsnloc.analysis.simulated_runs import with_value
    from wsnloc.sim.newcom import twr_clock_bias_m

    c = campaign.spec["speed_of_light_mps"]
    spec = {"twr_clock_ppm": 20.0, "twr_reply_time_us": 300.0}
    bias = twr_clock_bias_m(spec, np.random.default_rng(3), 12, c)
    offsets = np.random.default_rng(3).uniform(-20e-6, 20e-6, 13)
    assert bias == pytest.approx(c * 300e-6 * (offsets[0] - offsets[1:]) / 2)
    assert np.abs(bias).max() <= c * 300e-6 * 40e-6 / 2 and np.abs(bias).max() > 0.1
    assert not twr_clock_bias_m({"twr_clock_ppm": 20.0, "twr_reply_time_us": 0.0}, np.random.default_rng(3), 12, c).any()

    biased = with_value(campaign, ("radio", "uwb", "twr_reply_time_us"), 300.0)
    run = simulate_run(biased, "constant", run_seed_sequence(7, "newcom", "constant", 1), tmp_path / "biased")
    base, shifted = (ingest_run(r, campaign)[0]["ranges"] for r in (simulated_run, run))
    valid = (base["status"] == 0).to_numpy()
    step = (shifted["range_m"] - base["range_m"])[valid].groupby(base["anchor_id"][valid])
    assert (step.max() - step.min()).max() < 1e-3          # constant per anchor (ps rounding only)
    assert step.mean().abs().max() > 0.1 and step.mean().nunique() == len(step.mean())


def test_2009_hardware_class_ranges_worse_than_the_spec_class(campaign, simulated_run, tmp_path):
    from wsnloc.analysis.nlos_severity import level_campaign
    from wsnloc.metrics.ranging import range_errors

    era = level_campaign(campaign, {"hardware_class": "ieee802154a_2009"}, "levels.era")
    assert era.section("radio", "uwb")["cir_tap_ns"] > campaign.section("radio", "uwb")["cir_tap_ns"]
    run = simulate_run(era, "constant", run_seed_sequence(7, "newcom", "constant", 1), tmp_path / "era")
    errors = {}
    for name, c, r in (("spec", campaign, simulated_run), ("era", era, run)):
        t = ingest_run(r, c)[0]
        e = range_errors(t["ranges"], t["truth"], c)
        # NLOS compared on the links both classes close (<= 10 m): the 2009 class's sensitivity
        # drops the longer, worse NLOS links, which would lower its median by selection alone
        errors[name] = {"los": np.median(np.abs(e["error_m"][e["walls"] == 0])),
                        "nlos": np.median(np.abs(e["error_m"][(e["walls"] > 0) & (e["true_distance_m"] <= 10)])),
                        "spread": np.std(e["error_m"][e["walls"] == 0])}
    assert errors["era"]["los"] > errors["spec"]["los"] + 0.1
    assert errors["era"]["nlos"] > errors["spec"]["nlos"]
    assert errors["era"]["spread"] > errors["spec"]["spread"]
