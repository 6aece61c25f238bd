"""Low-cost MEMS IMU on the cart: 3-axis accelerometer and z gyroscope, raw integer counts.

Body frame: x forward (along the path), y left, z up. For a cart following a planar path
at speed v with tangential acceleration a and path curvature kappa (1/m, left > 0):
  specific force f = [a, v^2 kappa, g]     (m/s^2)
  yaw rate        w_z = v kappa            (rad/s)
Sensor model (`noise_model: mems`): f + per-run bias + white noise (density * sqrt(fs/2))
+ drive vibration (tones whose total RMS grows linearly with speed); gyro likewise with
bias and white noise. `noise_model: snr60` (paper B's simulation) instead adds only white
Gaussian noise whose power is the signal power / 10^(SNR/10).
Counts = round(value * scale), clipped to the converter's signed range.
"""

from __future__ import annotations

import numpy as np

MICRO_G = 1e-6


def body_motion(v, a, curvature, gravity: float) -> tuple[np.ndarray, np.ndarray]:
    """True specific force (N, 3) in m/s^2 and yaw rate (N,) in rad/s."""
    force = np.column_stack([a, v**2 * curvature, np.full_like(v, gravity)])
    return force, v * curvature


def vibration(t, v, spec: dict, rng: np.random.Generator) -> np.ndarray:
    """(N, 3) drive vibration in m/s^2: sum of tones, RMS = ref_rms * v / ref_speed."""
    tones = np.asarray(spec["vibration_tones_hz"], dtype=float)
    weights = np.asarray(spec.get("vibration_axis_weights", [0.5, 0.5, 1.0]), dtype=float)
    amplitude = spec["vibration_mps2_at_ref_speed"] * np.sqrt(2.0 / len(tones)) \
        * (v / spec["vibration_ref_speed_mps"])
    phases = rng.uniform(0.0, 2 * np.pi, (3, len(tones)))
    out = np.empty((len(t), 3))
    for axis in range(3):
        waves = np.sin(2 * np.pi * tones[None, :] * t[:, None] + phases[axis][None, :]).sum(axis=1)
        out[:, axis] = weights[axis] * amplitude * waves
    return out


def sensor_readings(t, force, yaw_rate, v, spec: dict, gravity: float,
                    rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Measured specific force (N, 3) m/s^2 and yaw rate (N,) rad/s before quantization."""
    fs = spec["rate_hz"]
    n = len(t)
    if spec.get("noise_model", "mems") == "snr60":
        snr = 10 ** (spec["snr_db"] / 10)
        dynamic = force - np.array([0.0, 0.0, gravity])
        accel_sigma = np.sqrt(np.mean(dynamic[:, :2] ** 2) / snr)
        gyro_sigma = np.sqrt(np.mean(yaw_rate**2) / snr)
        accel = force + rng.normal(0.0, accel_sigma, (n, 3))
        gyro = yaw_rate + rng.normal(0.0, gyro_sigma, n)
        return accel, gyro
    accel_bias = rng.normal(0.0, spec["accel_bias_sigma_mps2"], 3)
    accel_sigma = spec["accel_noise_ug_per_rthz"] * MICRO_G * gravity * np.sqrt(fs / 2.0)
    accel = force + accel_bias + rng.normal(0.0, accel_sigma, (n, 3)) + vibration(t, v, spec, rng)
    gyro_bias = np.deg2rad(rng.normal(0.0, spec["gyro_bias_sigma_dps"]))
    gyro_sigma = np.deg2rad(spec["gyro_noise_dps_per_rthz"] * np.sqrt(fs / 2.0))
    gyro = yaw_rate + gyro_bias + rng.normal(0.0, gyro_sigma, n)
    return accel, gyro


def to_counts(accel, gyro, spec: dict, gravity: float) -> tuple[np.ndarray, np.ndarray]:
    """Quantize to signed integer counts of the configured converters."""
    def quantize(values, scale, bits):
        limit = 2 ** (bits - 1)
        return np.clip(np.round(values * scale), -limit, limit - 1).astype(np.int64)

    accel_counts = quantize(accel / gravity, spec["accel_lsb_per_g"], spec["accel_bits"])
    gyro_counts = quantize(np.rad2deg(gyro), spec["gyro_lsb_per_dps"], spec["gyro_bits"])
    return accel_counts, gyro_counts
