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


def test_first_path_is_never_later_than_strongest_path(campaign):
    spec = campaign.section("radio", "uwb")
    rng = np.random.default_rng(0)
    for name in ("CM3", "CM4"):
        for _ in range(200):
            taps = uwb_channel.tap_powers(*uwb_channel.impulse_response(spec["channel_models"][name], rng), 1.0)
            first = uwb_channel.detect_delay_ns(taps, 1.0, "first_path", 15.0)
            strongest = uwb_channel.detect_delay_ns(taps, 1.0, "strongest_path", 15.0)
            assert 0.0 <= first <= strongest


def test_nlos_strongest_path_is_biased_by_the_diffuse_first_cluster(campaign):
    """CM4's rising first cluster delays the strongest tap by several ns; CM3's LOS ray does not."""
    spec = campaign.section("radio", "uwb")
    rng = np.random.default_rng(1)

    def median_delay(name):
        delays = [uwb_channel.detect_delay_ns(uwb_channel.tap_powers(
            *uwb_channel.impulse_response(spec["channel_models"][name], rng), 1.0), 1.0, "strongest_path", 15.0)
            for _ in range(400)]
        return np.median(delays)

    assert median_delay("CM4") > 5.0 > median_delay("CM3")


def test_detector_names_are_checked():
    with pytest.raises(ValueError, match="unknown UWB detector"):
        uwb_channel.detect_delay_ns(np.ones(3), 1.0, "earliest", 15.0)


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
