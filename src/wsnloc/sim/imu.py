"""Low-cost MEMS IMU on the cart: 3-axis accelerometer and z gyroscope, raw integer counts.

Body frame: x forward (along the path), y left, z up. For a cart following a planar path
at speed v with tangential acceleration a and path curvature kappa (1/m, left > 0):
  specific force f = [a, v^2 kappa, g]     (m/s^2)
  yaw rate        w_z = v kappa            (rad/s)
Sensor model (`noise_model: mems`): f + per-run bias + white noise (density * sqrt(fs/2))
+ drive vibration (tones whose total RMS grows linearly with speed); gyro likewise with
bias and white noise. Optional tilt (`tilt_leakage`, keys mount_tilt_sigma_deg,
floor_slope_sigma_deg, floor_slope_correlation_m; absent = a level sensor): the sensor's
pitch theta and roll phi are a per-run mounting tilt plus the floor's slope under the cart
along the path, so gravity leaks into the horizontal axes,
  f_x += g sin(theta),  f_y -= g cos(theta) sin(phi),  f_z = g cos(theta) cos(phi);
the slope term varies at v / correlation length (0.2-2 Hz for a cart at 0.2-0.6 m/s on a
floor undulating over ~0.3 m), inside the 5 Hz output's band: no low-pass removes it.

`noise_model: snr` is paper B's simulated unit: "accelerometers afflicted by a measurement
additive gaussian noise N and a sampling rate equal to 5 Hz", with "an SNR of 60dB"
matching the real sensor's output. Read literally:
  signal   the noise-free accelerometer OUTPUT, i.e. the specific force f (all three axes,
           gravity on z included: that is what the sensor outputs, and what the paper
           compared with the real accelerometer's output);
  SNR      P_signal / sigma_5^2 with P_signal = mean over samples and axes of f_i^2, so
           sigma_5 = sqrt(P_signal / 10^(SNR/10)) per axis at the 5 Hz output;
  noise    white at 5 Hz with that sigma_5. The log is written at fs = 500 Hz and reduced
           to 5 Hz by an anti-aliasing low-pass (wsnloc.signal.resample), so the noise is
           written white at fs with sigma_fs = sigma_5 sqrt(fs / f_out): a low-pass with cut-off
           f_out / 2 keeps the fraction f_out / fs of a white noise's variance, leaving
           sigma_5 on the 5 Hz samples (a noise held over each 0.2 s would not: the low-pass
           would smooth it and correlate successive samples). With the workflow's Kaiser FIR
           (beta 8) the 5 Hz noise measures 0.97-1.0 sigma_5, lag-1 correlation < 0.1
           (tests/test_imu_snr.py).
The gyro gets no noise ("the only noisy impairment" of the simulation is the channel).
Counts = round(value * scale), clipped to the converter's signed range.
"""

from __future__ import annotations

import numpy as np

from wsnloc.campaign import Campaign

MICRO_G = 1e-6
NOISE_MODELS = ("mems", "snr")
DEFAULT_NOISE_MODEL = "mems"       # campaign imu.noise_model when not given
ACCEL_BIAS, GYRO_BIAS = "accel_bias_sigma_mps2", "gyro_bias_sigma_dps"     # campaign imu keys of the per-run biases


def noise_model_of(campaign: Campaign, scenario: str) -> str:
    """The IMU noise model a scenario is simulated with: its overrides.imu_noise_model, else
    the campaign's imu.noise_model, else DEFAULT_NOISE_MODEL."""
    override = campaign.section("scenarios", scenario).get("overrides", {}).get("imu_noise_model")
    return override or campaign.spec.get("imu", {}).get("noise_model", DEFAULT_NOISE_MODEL)


def bias_sigma(campaign: Campaign, scenario: str, key: str) -> float:
    """The per-run bias sigma a scenario's IMU is simulated with, by campaign key: imu.`key`
    (ACCEL_BIAS in m/s^2 per axis, GYRO_BIAS in deg/s) under the `mems`
    noise model, 0 under paper B's `snr` model, which has no bias (noise_model_of)."""
    return float(campaign.section("imu", key)) if noise_model_of(campaign, scenario) == "mems" else 0.0


def body_motion(v, a, curvature, gravity: float) -> tuple[np.ndarray, np.ndarray]:
    """True specific force (N, 3) in m/s^2 and yaw rate (N,) in rad/s."""
    force = np.column_stack([a, v**2 * curvature, np.full_like(v, gravity)])
    return force, v * curvature


PAIRWISE_FROM_TONES = 8   # numpy sums 8 or more terms of a row in pairwise blocks, fewer in sequence


def _sum_over_tones(waves: np.ndarray) -> np.ndarray:
    """sum_j waves[j] of a (tones, N) array, (N,): per sample, the float numpy's sum over the last
    axis of the (N, tones) array gives. Below PAIRWISE_FROM_TONES tones that is the sequential
    ((w_0 + w_1) + w_2) + ..., added here row by row over contiguous rows; from there on the sum
    is taken on the (N, tones) copy."""
    if len(waves) >= PAIRWISE_FROM_TONES:
        return np.ascontiguousarray(waves.T).sum(axis=1)
    total = waves[0].copy()
    for wave in waves[1:]:
        total += wave
    return total


def vibration(t, v, spec: dict, rng: np.random.Generator) -> np.ndarray:
    """(N, 3) drive vibration in m/s^2: sum of tones, RMS = ref_rms * v / ref_speed.

    axis i: w_i A(v) sum_j sin(2 pi f_j t + phi_ij), A(v) = ref_rms sqrt(2 / n_tones) v / ref_speed,
    t in s, f_j in Hz, phi_ij in rad. The angles 2 pi f_j t are computed once for the three axes,
    laid out tone by tone (contiguous sines), and summed as numpy sums an (N, tones) array over
    its tones (_sum_over_tones). Samples with A(v) = 0 (cart at rest) are +0 without evaluating
    their sines: the formula gives +-0 there, and x + 0 == x + (-0) for every accelerometer sum x
    it is added to except x = -0 (f + bias + white noise is never exactly -0).
    """
    tones = np.asarray(spec["vibration_tones_hz"], dtype=float)
    weights = np.asarray(spec.get("vibration_axis_weights", [0.5, 0.5, 1.0]), dtype=float)
    amplitude = spec["vibration_mps2_at_ref_speed"] * np.sqrt(2.0 / len(tones)) \
        * (v / spec["vibration_ref_speed_mps"])
    phases = rng.uniform(0.0, 2 * np.pi, (3, len(tones)))
    moving = np.flatnonzero(amplitude)
    amplitude = amplitude[moving]
    angle = (2 * np.pi * tones)[:, None] * np.asarray(t)[moving][None, :]    # (tones, moving samples)
    waves = np.empty_like(angle)
    out = np.zeros((len(t), 3))
    for axis in range(3):
        np.sin(np.add(angle, phases[axis][:, None], out=waves), out=waves)
        out[moving, axis] = weights[axis] * amplitude * _sum_over_tones(waves)
    return out


def tilt_angles(s, spec: dict, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Pitch and roll (rad) of the sensor at arc lengths s (m, non-decreasing along the run).

    angle(s) = mount + slope(s): mount ~ N(0, mount_tilt_sigma) once per run; slope a Gaussian
    process along the path with autocorrelation sigma^2 exp(-|ds| / ell) (floor_slope_sigma_deg,
    floor_slope_correlation_m), drawn on a 1 cm grid of the path as the exact AR(1) recursion
    x_k = rho x_{k-1} + sqrt(1 - rho^2) sigma e_k, rho = exp(-0.01 / ell) (_ar1) and
    interpolated at s; independent for pitch and roll. Zero angles without the keys.
    """
    s = np.asarray(s, dtype=float)
    mount_sigma = np.deg2rad(spec.get("mount_tilt_sigma_deg", 0.0))
    slope_sigma = np.deg2rad(spec.get("floor_slope_sigma_deg", 0.0))
    if mount_sigma == 0.0 and slope_sigma == 0.0:
        return np.zeros_like(s), np.zeros_like(s)
    mount = rng.normal(0.0, mount_sigma, 2)
    grid_step = 0.01
    grid = np.arange(0.0, (s.max(initial=0.0) if len(s) else 0.0) + 2 * grid_step, grid_step)
    rho = np.exp(-grid_step / spec["floor_slope_correlation_m"])
    shocks = rng.normal(0.0, slope_sigma, (2, len(grid)))
    shocks[:, 1:] *= np.sqrt(1.0 - rho**2)
    slope = [_ar1(row, rho) for row in shocks]                   # x_0 = e_0 (stationary start)
    return mount[0] + np.interp(s, grid, slope[0]), mount[1] + np.interp(s, grid, slope[1])


def _ar1(shocks: np.ndarray, rho: float) -> np.ndarray:
    """x_k = shocks_k + rho x_{k-1}, x_{-1} = 0, in sequence: the floats
    scipy.signal.lfilter([1], [1, -rho], shocks) gives (importing scipy.signal costs a
    simulation job about 0.6 s of CPU, the recursion a few ms per run)."""
    out, previous, rho = [], 0.0, float(rho)
    for shock in shocks.tolist():
        previous = shock + rho * previous
        out.append(previous)
    return np.array(out)


def tilt_leakage(force: np.ndarray, pitch: np.ndarray, roll: np.ndarray, gravity: float) -> np.ndarray:
    """Specific force (N, 3) of a sensor tilted by pitch, roll (rad): gravity leaks into x and y
    (module docstring); the motion's own horizontal force is not rotated (second order)."""
    out = np.array(force, dtype=float)
    out[:, 0] += gravity * np.sin(pitch)
    out[:, 1] -= gravity * np.cos(pitch) * np.sin(roll)
    out[:, 2] = gravity * np.cos(pitch) * np.cos(roll)
    return out


def snr_noise_sigma(force: np.ndarray, snr_db: float) -> float:
    """Accelerometer noise sigma (m/s^2, per axis) at the output rate for a given SNR (dB).

    sigma = sqrt(P / 10^(SNR/10)),  P = mean_{k, i} f_i[k]^2  (noise-free specific force,
    (N, 3) in m/s^2, gravity included: the sensor's output).
    """
    power = float(np.mean(np.asarray(force, dtype=float) ** 2))
    return float(np.sqrt(power / 10 ** (snr_db / 10)))


def sensor_readings(t, force, yaw_rate, v, spec: dict, gravity: float,
                    rng: np.random.Generator, s=None) -> tuple[np.ndarray, np.ndarray]:
    """Measured specific force (N, 3) m/s^2 and yaw rate (N,) rad/s before quantization;
    s (m): arc length at each sample, needed by the tilt model (`tilt_angles`)."""
    fs = spec["rate_hz"]
    n = len(t)
    model = spec.get("noise_model", DEFAULT_NOISE_MODEL)
    if model not in NOISE_MODELS:
        raise ValueError(f"imu.noise_model: unknown noise model {model!r}; expected one of {NOISE_MODELS}")
    if model == "snr":
        sigma_out = snr_noise_sigma(force, spec["snr_db"])
        sigma_fs = sigma_out * np.sqrt(fs / spec["snr_output_rate_hz"])
        return force + rng.normal(0.0, sigma_fs, (n, 3)), np.array(yaw_rate, dtype=float)
    if spec.get("mount_tilt_sigma_deg", 0.0) or spec.get("floor_slope_sigma_deg", 0.0):
        force = tilt_leakage(force, *tilt_angles(s, spec, rng), gravity)
    accel_bias = rng.normal(0.0, spec[ACCEL_BIAS], 3)
    accel_sigma = spec["accel_noise_ug_per_rthz"] * MICRO_G * gravity * np.sqrt(fs / 2.0)
    accel = force + accel_bias                                  # ((f + b) + noise) + vibration, drawn in that order
    accel += rng.normal(0.0, accel_sigma, (n, 3))
    accel += vibration(t, v, spec, rng)
    gyro_bias = np.deg2rad(rng.normal(0.0, spec[GYRO_BIAS]))
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
