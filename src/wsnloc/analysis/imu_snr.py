"""Dead-reckoning RMSE against the accelerometer SNR of paper B's simulated IMU.

For each SNR and run: the campaign simulator's trajectory and `imu.log` lines (noise model
`snr`, wsnloc.sim.imu), parsed by the project's reader, resampled to 5 Hz
(wsnloc.signal.resample), dead-reckoned from the true start pose with the bias taken over the
first rest (wsnloc.inertial.dead_reckoning), and scored against the noise-free path position:
  RMSE = sqrt(mean_k ||p_k - p_true(t_k)||^2)   (m, over the 5 Hz samples of the run).
Run r uses the seeds of run r of the workflow (wsnloc.sim.seeding), so the runs are paired
across SNRs.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.inertial.dead_reckoning import dead_reckon, static_bias
from wsnloc.io.newcom import parse_imu
from wsnloc.io.rawlines import Quarantine, raw_from_bytes
from wsnloc.metrics.stats import error_summary, mean_interval
from wsnloc.signal.resample import resample_imu
from wsnloc.sim import trajectory as motion
from wsnloc.sim.logs import imu_text
from wsnloc.sim.seeding import model_rng, run_seed_sequence


def with_snr(campaign: Campaign, snr_db: float) -> Campaign:
    """A copy of the campaign whose IMU uses the `snr` noise model at `snr_db` dB."""
    spec = copy.deepcopy(campaign.spec)
    spec["imu"].update(noise_model="snr", snr_db=float(snr_db))
    return Campaign(campaign.name, campaign.format, spec, campaign.source)


def run_trajectory(campaign: Campaign, scenario: str, run: int, seed: int,
                   dataset: str = "newcom") -> motion.Trajectory:
    """The simulator's motion of run `run` of `scenario` (its seeds: wsnloc.sim.seeding); the
    IMU noise model does not enter it, so every SNR of a run shares it."""
    seeds = run_seed_sequence(seed, dataset, scenario, run)
    return motion.for_scenario(campaign.section("scenarios", scenario), campaign.path.length,
                               model_rng(seeds, "motion"))


def dead_reckoning_rmse(campaign: Campaign, scenario: str, snr_db: float, run: int, seed: int,
                        resample: dict, static_start_s: float, dataset: str = "newcom",
                        traj: motion.Trajectory | None = None) -> float:
    """RMSE (m) of 5 Hz dead reckoning over one simulated run at accelerometer SNR `snr_db`.

    resample: the workflow's `resample` settings (rate_hz, grid_rate_hz, max_gap_s, kaiser_beta).
    traj: the run's motion (run_trajectory), when the caller already has it.
    """
    noisy = with_snr(campaign, snr_db)
    seeds = run_seed_sequence(seed, dataset, scenario, run)
    if traj is None:
        traj = run_trajectory(noisy, scenario, run, seed, dataset)
    quarantine = Quarantine()
    text = imu_text(noisy, traj, model_rng(seeds, "imu"), "snr", clock_ms=0)
    imu = resample_imu(parse_imu(raw_from_bytes("imu.log", text.encode("ascii"), quarantine), noisy, quarantine),
                       **resample)
    x0, y0, heading0 = noisy.path.start_pose()
    track = dead_reckon(imu, x0, y0, heading0, static_bias(imu, static_start_s))
    truth = noisy.path.evaluate(traj.at(track["t"].to_numpy())["s"])
    errors = np.hypot(track["x"].to_numpy() - truth["x"], track["y"].to_numpy() - truth["y"])
    return error_summary(errors)["rmse"]


def rmse_against_snr(campaign: Campaign, scenario: str, snrs_db, runs: int, seed: int,
                     resample: dict, static_start_s: float, dataset: str = "newcom") -> pd.DataFrame:
    """Dead-reckoning RMSE per SNR: columns snr_db, rmse_m (mean over runs), ci95_low,
    ci95_high (95% interval of the mean, metrics.stats.mean_interval on the non-negative scale;
    NaN with fewer than MIN_INTERVAL_RUNS runs), runs, and run_rmse_m (the per-run values,
    runs 1..`runs`, for paired comparisons). Each run's motion is simulated once for all SNRs."""
    if runs < 1:
        raise ValueError(f"runs must be at least 1, got {runs}")
    motions = {run: run_trajectory(campaign, scenario, run, seed, dataset) for run in range(1, runs + 1)}
    rows = []
    for snr_db in snrs_db:
        values = [dead_reckoning_rmse(campaign, scenario, snr_db, run, seed, resample, static_start_s, dataset, traj)
                  for run, traj in motions.items()]
        mean, low, high = mean_interval(values, "nonnegative")
        rows.append({"snr_db": float(snr_db), "rmse_m": mean, "ci95_low": low, "ci95_high": high,
                     "runs": len(values), "run_rmse_m": values})
    return pd.DataFrame(rows)
