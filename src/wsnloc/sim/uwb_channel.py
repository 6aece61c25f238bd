"""IEEE 802.15.4a channel impulse responses and time-of-arrival detection.

Model (Molisch et al., IEEE 802.15.4a channel model final report, 2005; parameters of
CM3 office LOS and CM4 office NLOS in the campaign file):
- L = max(1, Poisson(L_mean)) clusters; cluster arrivals T_l Poisson with rate Lambda
  (T_1 = 0).
- Rays in a cluster: arrivals from the two-process mixture
  p(tau_k | tau_{k-1}) = beta*l1*exp(-l1*dt) + (1-beta)*l2*exp(-l2*dt).
- Cluster energy: 10 log10(Omega_l) = 10 log10(exp(-T_l / Gamma)) + N(0, sigma_cluster).
- Ray mean power: E|a|^2 = Omega_l / (gamma (1 - beta) l1 + beta l2 + 1)) exp(-tau / gamma);
  for CM4 the first cluster is diffuse:
  E|a|^2 ~ Omega_1 (1 - chi exp(-tau/gamma_rise)) exp(-tau/gamma_1)
           (gamma_1 + gamma_rise) / (gamma_1 (gamma_1 + gamma_rise (1 - chi))).
- Small-scale fading: Nakagami-m, |a|^2 ~ Gamma(m, E|a|^2 / m) with m log-normal
  (mean m0, std sigma_m0, natural-log domain as in the reference code), m >= 1/2; in LOS
  the first ray of each cluster has the deterministic m of `first_ray_m`.
The rays are summed with random phases into receiver taps of `cir_tap_ns` (the
accumulator of a DW1000-class receiver), and a detector picks a tap:
- `first_path`: the first tap whose power is within `leading_edge_threshold_db` of the peak;
- `strongest_path`: the peak tap.
"""

from __future__ import annotations

import numpy as np

RAY_SPAN = 5.0       # rays are drawn up to 5 decay constants (-21.7 dB) into a cluster
CLUSTER_SPAN = 5.0   # clusters are drawn up to 5 cluster decay constants


def impulse_response(model: dict, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One channel realisation: (delays in ns relative to the first arrival, complex amplitudes)."""
    n_clusters = max(1, rng.poisson(model["mean_clusters"]))
    gaps = rng.exponential(1.0 / model["cluster_rate_per_ns"], size=n_clusters - 1)
    cluster_t = np.concatenate([[0.0], np.cumsum(gaps)])
    cluster_t = cluster_t[cluster_t < CLUSTER_SPAN * model["cluster_decay_ns"]]
    n_clusters = len(cluster_t)
    energy_db = -10 * np.log10(np.e) * cluster_t / model["cluster_decay_ns"] \
        + rng.normal(0.0, model["cluster_sigma_db"], n_clusters)
    omega = 10 ** (energy_db / 10)

    beta, l1, l2 = model["ray_mixture_beta"], model["ray_rate_1_per_ns"], model["ray_rate_2_per_ns"]
    diffuse = bool(model.get("diffuse_first_cluster", False))
    decay = np.full(n_clusters, float(model["ray_decay_ns"]))
    if diffuse:
        decay[0] = model["first_cluster_decay_ns"]
    span = RAY_SPAN * decay.max()
    n_rays = int(span * max(l1, l2) * 1.3) + 10
    slow = rng.random((n_clusters, n_rays)) < beta
    inter = np.where(slow, rng.exponential(1 / l1, (n_clusters, n_rays)),
                     rng.exponential(1 / l2, (n_clusters, n_rays)))
    inter[:, 0] = 0.0                                  # first ray at the cluster arrival
    tau = np.cumsum(inter, axis=1)
    keep = tau < RAY_SPAN * decay[:, None]

    mean_power = omega[:, None] / (decay[:, None] * ((1 - beta) * l1 + beta * l2 + 1)) \
        * np.exp(-tau / decay[:, None])
    if diffuse:
        rise, g1, chi = model["rise_ns"], model["first_cluster_decay_ns"], model["diffuse_chi"]
        mean_power[0] = omega[0] * (1 - chi * np.exp(-tau[0] / rise)) * np.exp(-tau[0] / g1) \
            * (g1 + rise) / (g1 * (g1 + rise * (1 - chi)))
    m = np.maximum(np.exp(rng.normal(model["nakagami_m0"], model["nakagami_sigma_m0"], tau.shape)), 0.5)
    if model.get("first_ray_m") is not None:
        m[:, 0] = model["first_ray_m"]
    power = rng.gamma(m, mean_power / m)
    phase = rng.uniform(0.0, 2 * np.pi, tau.shape)
    delays = (cluster_t[:, None] + tau)[keep]
    amplitudes = (np.sqrt(power) * np.exp(1j * phase))[keep]
    return delays, amplitudes


def tap_powers(delays: np.ndarray, amplitudes: np.ndarray, tap_ns: float) -> np.ndarray:
    """Coherent sum of the rays falling into each receiver tap; returns |h_tap|^2."""
    index = np.floor(delays / tap_ns).astype(int)
    real = np.bincount(index, weights=amplitudes.real)
    imag = np.bincount(index, weights=amplitudes.imag)
    return real**2 + imag**2


def detect_delay_ns(powers: np.ndarray, tap_ns: float, detector: str, threshold_db: float) -> float:
    """Delay (ns) of the tap a detector picks: leading edge (first_path) or peak (strongest_path)."""
    peak = int(np.argmax(powers))
    if detector == "strongest_path":
        return peak * tap_ns
    if detector == "first_path":
        above = np.flatnonzero(powers >= powers[peak] * 10 ** (-threshold_db / 10))
        return float(above[0]) * tap_ns
    raise ValueError(f"unknown UWB detector {detector!r} (expected first_path or strongest_path)")
