"""Paper B's `snr` accelerometer reading: noise white at 5 Hz, sigma from the output's power,
checked through the project's resampler; and the dead-reckoning RMSE against SNR study."""

import numpy as np
import pandas as pd
import pytest
import yaml

from wsnloc.analysis.imu_snr import rmse_against_snr
from wsnloc.signal.resample import resample_imu
from wsnloc.sim.imu import body_motion, sensor_readings, snr_noise_sigma, to_counts

from conftest import ROOT

RESAMPLE = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["resample"]


def test_sigma_from_the_output_power_closed_form():
    g = 9.80665
    at_rest = np.tile([0.0, 0.0, g], (100, 1))          # the output is gravity on z only
    # P = g^2 / 3 per axis; SNR 60 dB -> sigma = sqrt(P) / 1000
    assert snr_noise_sigma(at_rest, 60.0) == pytest.approx(g / np.sqrt(3) / 1000)
    moving = np.array([[0.3, 0.4, g], [-0.3, -0.4, g]])
    assert snr_noise_sigma(moving, 40.0) == pytest.approx(np.sqrt((0.25 + g**2) / 3) / 100)


def _at_rest_counts(campaign, snr_db, seconds, seed):
    """500 Hz output of the snr sensor at rest, quantized by the campaign's converters, in SI."""
    spec = dict(campaign.section("imu"), noise_model="snr", snr_db=snr_db)
    g = campaign.spec["gravity_mps2"]
    t = np.arange(0.0, seconds, 1.0 / spec["rate_hz"])
    zeros = np.zeros_like(t)
    force, yaw = body_motion(zeros, zeros, zeros, g)
    accel, gyro = sensor_readings(t, force, yaw, zeros, spec, g, np.random.default_rng(seed))
    acc_counts, gyro_counts = to_counts(accel, gyro, spec, g)
    frame = pd.DataFrame(acc_counts / spec["accel_lsb_per_g"] * g, columns=["ax", "ay", "az"])
    frame.insert(0, "t", t)
    frame["gz"] = np.deg2rad(gyro_counts / spec["gyro_lsb_per_dps"])
    return frame, snr_noise_sigma(force, snr_db)


def test_noise_is_white_at_5hz_with_the_stated_sigma_after_the_resampler(campaign):
    raw, sigma = _at_rest_counts(campaign, 60.0, 600.0, seed=11)
    # the 500 Hz log carries sigma * sqrt(500 / 5) = 10 sigma (several converter steps)
    assert raw["ax"].std() == pytest.approx(10 * sigma, rel=0.03)
    five_hz = resample_imu(raw, **RESAMPLE).iloc[20:-20]     # drop the filter's edge samples
    assert np.median(np.diff(five_hz["t"])) == pytest.approx(0.2)
    for axis in ("ax", "ay"):
        noise = five_hz[axis].to_numpy()
        assert noise.std() == pytest.approx(sigma, rel=0.08)   # 2900 samples: sampling error ~1.3%
        lag1 = np.corrcoef(noise[:-1], noise[1:])[0, 1]
        assert abs(lag1) < 0.1                                 # white at 5 Hz, not smoothed
    assert (five_hz["gz"] == 0).all()                          # no gyro noise in this reading


def test_study_scales_with_noise_and_reaches_the_noise_free_floor(campaign):
    runs = rmse_against_snr(campaign, "b_simulation", [30.0, 50.0, 140.0], runs=2, seed=5,
                            resample=RESAMPLE, static_start_s=0.0)
    assert runs["runs"].tolist() == [2, 2, 2]
    assert runs[["ci95_low", "ci95_high"]].isna().all().all()    # 2 runs < MIN_INTERVAL_RUNS: no interval drawn
    low_snr, mid_snr, noise_free = (np.array(v) for v in runs["run_rmse_m"])
    # Same seeds, same standard-normal draws: 20 dB less SNR is 10x the noise, and the
    # noise-driven error of a linear dead reckoning grows 10x; the noise-free floor (about 1 m on
    # paper B's 18 m path, entered in motion) is of the order of the 50 dB error, so the ratio of
    # the RMSEs lies between 5 and 20 rather than at 10.
    assert np.all((low_snr / mid_snr > 5.0) & (low_snr / mid_snr < 20.0))
    # Without noise only the converter step and the 5 Hz integration remain: about a metre.
    assert (noise_free < 1.5).all() and (noise_free < low_snr).all()


def test_study_rejects_no_runs(campaign):
    with pytest.raises(ValueError, match="runs"):
        rmse_against_snr(campaign, "b_simulation", [60.0], runs=0, seed=5, resample=RESAMPLE,
                         static_start_s=0.0)


@pytest.mark.parametrize("change, message", [
    ({"noise_model": "snr60"}, "'imu.noise_model': 'snr60' is not one of"),
    ({"noise_model": "snr", "snr_output_rate_hz": None}, "'imu.snr_output_rate_hz': required"),
])
def test_campaign_file_names_a_bad_imu_noise_setting(tmp_path, change, message):
    from wsnloc.campaign import Campaign
    from wsnloc.errors import ConfigError

    spec = yaml.safe_load((ROOT / "config" / "campaigns" / "newcom.yaml").read_text())
    for key, value in change.items():
        if value is None:
            del spec["imu"][key]
        else:
            spec["imu"][key] = value
    path = tmp_path / "campaign.yaml"
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(ConfigError, match=message):
        Campaign.load(path)


def test_study_shares_each_runs_motion_across_snrs_without_changing_it(campaign):
    from wsnloc.analysis.imu_snr import dead_reckoning_rmse
    curve = rmse_against_snr(campaign, "b_simulation", [40.0, 60.0], runs=2, seed=5, resample=RESAMPLE,
                             static_start_s=0.0)
    alone = [[dead_reckoning_rmse(campaign, "b_simulation", snr, run, 5, RESAMPLE, 0.0) for run in (1, 2)]
             for snr in (40.0, 60.0)]
    assert curve["run_rmse_m"].tolist() == alone      # exactly: the motion of a run does not depend on the SNR
