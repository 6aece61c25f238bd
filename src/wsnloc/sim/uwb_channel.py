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
Every function works on a batch of independent links at once (arrays over a link axis),
so that a run's ~10^3 channel realisations cost a few array operations, not a Python loop.
"""

from __future__ import annotations

import numpy as np

RAY_SPAN = 5.0       # rays are drawn up to 5 decay constants (-21.7 dB) into a cluster
CLUSTER_SPAN = 5.0   # clusters are drawn up to 5 cluster decay constants
LINKS_PER_BATCH = 512  # bounds the (links, clusters, rays) arrays to a few tens of MB
DETECTORS = ("first_path", "strongest_path")


def check_detector(detector: str) -> None:
    if detector not in DETECTORS:
        raise ValueError(f"unknown UWB detector {detector!r} (expected first_path or strongest_path)")


def impulse_responses(model: dict, rng: np.random.Generator, n_links: int
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`n_links` independent channel realisations, as flat arrays over all their rays:
    (link index, delay in ns relative to the link's first arrival, complex amplitude)."""
    n_clusters = np.maximum(1, rng.poisson(model["mean_clusters"], n_links))
    width = int(n_clusters.max())
    gaps = rng.exponential(1.0 / model["cluster_rate_per_ns"], (n_links, width - 1))
    cluster_t = np.concatenate([np.zeros((n_links, 1)), np.cumsum(gaps, axis=1)], axis=1)
    clusters = (np.arange(width)[None, :] < n_clusters[:, None]) \
        & (cluster_t < CLUSTER_SPAN * model["cluster_decay_ns"])
    energy_db = -10 * np.log10(np.e) * cluster_t / model["cluster_decay_ns"] \
        + rng.normal(0.0, model["cluster_sigma_db"], (n_links, width))
    omega = 10 ** (energy_db / 10)

    link, cluster = np.nonzero(clusters)               # the drawn clusters, flat
    beta, l1, l2 = model["ray_mixture_beta"], model["ray_rate_1_per_ns"], model["ray_rate_2_per_ns"]
    diffuse = bool(model.get("diffuse_first_cluster", False))
    decay = np.full(len(link), float(model["ray_decay_ns"]))
    if diffuse:
        decay[cluster == 0] = model["first_cluster_decay_ns"]
    n_rays = int(RAY_SPAN * decay.max() * max(l1, l2) * 1.3) + 10
    shape = (len(link), n_rays)
    rate = np.where(rng.random(shape) < beta, l1, l2)     # two-process mixture of arrival rates
    inter = rng.exponential(1.0, shape) / rate
    inter[:, 0] = 0.0                                      # first ray at the cluster arrival
    tau = np.cumsum(inter, axis=1)
    row, ray = np.nonzero(tau < RAY_SPAN * decay[:, None])
    tau, decay = tau[row, ray], decay[row]

    omega_ray = omega[link, cluster][row]
    mean_power = omega_ray / (decay * ((1 - beta) * l1 + beta * l2 + 1)) * np.exp(-tau / decay)
    if diffuse:
        rise, g1, chi = model["rise_ns"], model["first_cluster_decay_ns"], model["diffuse_chi"]
        first = cluster[row] == 0
        mean_power[first] = omega_ray[first] * (1 - chi * np.exp(-tau[first] / rise)) * np.exp(-tau[first] / g1) \
            * (g1 + rise) / (g1 * (g1 + rise * (1 - chi)))
    m = np.maximum(np.exp(rng.normal(model["nakagami_m0"], model["nakagami_sigma_m0"], len(row))), 0.5)
    if model.get("first_ray_m") is not None:
        m[ray == 0] = model["first_ray_m"]
    power = rng.gamma(m, mean_power / m)
    phase = rng.uniform(0.0, 2 * np.pi, len(row))
    magnitude = np.sqrt(power)
    delays = cluster_t[link, cluster][row] + tau
    return link[row], delays, magnitude * np.cos(phase) + 1j * (magnitude * np.sin(phase))


def tap_powers(link: np.ndarray, delays: np.ndarray, amplitudes: np.ndarray, tap_ns: float,
               n_links: int) -> np.ndarray:
    """Coherent sum of the rays falling into each receiver tap: |h_tap|^2, shape (n_links, taps)."""
    index = np.floor(delays / tap_ns).astype(int)
    n_taps = int(index.max()) + 1
    flat = link * n_taps + index
    real = np.bincount(flat, weights=amplitudes.real, minlength=n_links * n_taps)
    imag = np.bincount(flat, weights=amplitudes.imag, minlength=n_links * n_taps)
    return (real**2 + imag**2).reshape(n_links, n_taps)


def detect_delay_ns(powers: np.ndarray, tap_ns: float, detector: str, threshold_db: float) -> np.ndarray:
    """Delay (ns) of the tap a detector picks in each row of `powers` (links, taps): leading
    edge (first_path: first tap with power >= peak * 10^(-threshold_db / 10)) or peak
    (strongest_path)."""
    check_detector(detector)
    powers = np.atleast_2d(powers)
    peak = np.argmax(powers, axis=1)
    if detector == "strongest_path":
        return peak * tap_ns
    floor = powers[np.arange(len(powers)), peak] * 10 ** (-threshold_db / 10)
    return np.argmax(powers >= floor[:, None], axis=1) * tap_ns


def detected_delays_ns(model: dict, rng: np.random.Generator, n_links: int, tap_ns: float, detector: str,
                       threshold_db: float) -> np.ndarray:
    """Excess delay (ns) the detector reports on `n_links` independent links of one channel
    model, in batches of LINKS_PER_BATCH links."""
    check_detector(detector)
    out = [np.empty(0)]
    for start in range(0, n_links, LINKS_PER_BATCH):
        size = min(LINKS_PER_BATCH, n_links - start)
        link, delays, amplitudes = impulse_responses(model, rng, size)
        out.append(detect_delay_ns(tap_powers(link, delays, amplitudes, tap_ns, size), tap_ns, detector, threshold_db))
    return np.concatenate(out)
