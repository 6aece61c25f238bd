"""IEEE 802.15.4a channel impulse responses and time-of-arrival detection.

Model (Molisch et al., IEEE 802.15.4a channel model final report, 2005; parameters of
CM3 office LOS and CM4 office NLOS in the campaign file):
- L = max(1, Poisson(L_mean)) clusters; cluster arrivals T_l Poisson with rate Lambda
  (T_1 = 0).
- Rays in a cluster: arrivals from the two-process mixture
  p(tau_k | tau_{k-1}) = beta*l1*exp(-l1*dt) + (1-beta)*l2*exp(-l2*dt).
- Cluster energy: 10 log10(Omega_l) = 10 log10(exp(-T_l / Gamma)) + N(0, sigma_cluster).
- Ray mean power: E|a|^2 = Omega_l / (gamma ((1 - beta) l1 + beta l2 + 1)) exp(-tau / gamma);
  for CM4 the first cluster is diffuse:
  E|a|^2 ~ Omega_1 (1 - chi exp(-tau/gamma_rise)) exp(-tau/gamma_1)
           (gamma_1 + gamma_rise) / (gamma_1 (gamma_1 + gamma_rise (1 - chi))).
- Small-scale fading: Nakagami-m, |a|^2 ~ Gamma(m, E|a|^2 / m) with m log-normal
  (mean m0, std sigma_m0, natural-log domain as in the reference code), m >= 1/2; in LOS
  the first ray of each cluster has the deterministic m of `first_ray_m`.
With a link budget (sim.link_budget), each realisation is scaled to the link's received power
(its ray energies sum to P_rx) and the rays of its first cluster, the energy travelling along
the direct path, lose `direct_path_wall_loss_db` per wall crossed; the later clusters are
reflections that reach the receiver around the walls (through doors and the corridor).
The rays are summed with random phases into receiver taps of `cir_tap_ns` (the
accumulator of a DW1000-class receiver), and a detector picks a tap:
- `first_path`: the first tap whose power is within `leading_edge_threshold_db` of the peak
  and, with a link budget, at or above the noise-referenced threshold: when the direct path
  is below it, the leading edge is a later multipath component (a positive range error that
  grows as the direct path weakens with distance and walls);
- `strongest_path`: the peak tap.
No tap at or above the noise-referenced threshold: no detection (NaN).
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


def _ray_delays(rng: np.random.Generator, n_clusters: int, n_rays: int, beta: float, l1: float, l2: float,
                limit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ray arrival times (ns after their cluster's arrival) of `n_clusters` clusters, flat, and
    the number of rays kept per cluster (those with tau < limit, limit in ns per cluster).

    Draws u ~ U(0, 1) and e ~ Exp(1), both (n_clusters, n_rays), in that order; the inter-arrival
    time is e / l1 where u < beta, else e / l2 (two-process mixture, rates in 1/ns), 0 for the
    first ray, and tau_k = sum_{i <= k} inter_i (sequential cumsum). tau never decreases along
    a row, so the kept rays are a prefix of each row (at least the first, tau = 0 < limit).
    The rare u < beta rays (beta ~ 0.01) are divided by l1 apart and written back, so all the
    divisions happen in the one (n_clusters, n_rays) buffer of e (standard_exponential: the
    draws of exponential(1.0), 1.0 e being e).
    """
    shape = (n_clusters, n_rays)
    slow = np.flatnonzero(rng.random(shape) < beta)
    inter = rng.standard_exponential(shape)
    flat = inter.reshape(-1)                               # a view: inter is C-contiguous
    slow_inter = flat[slow] / l1
    np.divide(inter, l2, out=inter)
    flat[slow] = slow_inter
    inter[:, 0] = 0.0                                      # first ray at the cluster arrival
    tau = np.cumsum(inter, axis=1, out=inter)
    kept = tau < limit[:, None]
    return tau[kept], np.count_nonzero(kept, axis=1)


def _mean_ray_power(model: dict, omega: np.ndarray, decay: np.ndarray, first_cluster: np.ndarray,
                    tau: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Mean ray power E|a|^2 of every ray (flat, `counts` rays per cluster; omega, decay (ns)
    and first_cluster per cluster, tau in ns):

        Omega_l / (gamma ((1 - beta) l1 + beta l2 + 1)) exp(-tau / gamma), and for the rays of a
        diffuse first cluster (CM4) Omega_1 (1 - chi exp(-tau/gamma_rise)) exp(-tau/gamma_1)
        (gamma_1 + gamma_rise) / (gamma_1 (gamma_1 + gamma_rise (1 - chi))).

    The per-cluster factor Omega_l / (gamma ...) is computed once per cluster and repeated over
    its rays (the same floats as per ray). A diffuse first cluster's decay is gamma_1, so
    exp(-tau / decay) (one pass over all rays) is also its exp(-tau / gamma_1) factor.
    """
    beta, l1, l2 = model["ray_mixture_beta"], model["ray_rate_1_per_ns"], model["ray_rate_2_per_ns"]
    scale = np.repeat(omega / (decay * ((1 - beta) * l1 + beta * l2 + 1)), counts)
    power = np.negative(tau)
    power /= np.repeat(decay, counts)
    decayed = np.exp(power, out=power)
    if not model.get("diffuse_first_cluster", False):
        return np.multiply(scale, decayed, out=decayed)
    first = np.repeat(first_cluster, counts)
    rise, g1, chi = model["rise_ns"], model["first_cluster_decay_ns"], model["diffuse_chi"]
    first_power = np.repeat(omega[first_cluster], counts[first_cluster]) * (1 - chi * np.exp(-tau[first] / rise)) \
        * decayed[first] * (g1 + rise) / (g1 * (g1 + rise * (1 - chi)))
    np.multiply(scale, decayed, out=decayed)
    decayed[first] = first_power
    return decayed


def impulse_responses(model: dict, rng: np.random.Generator, n_links: int, received_mw: np.ndarray | None = None,
                      direct_gain: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`n_links` independent channel realisations, as flat arrays over all their rays:
    (link index, delay in ns relative to the link's first arrival, complex amplitude).

    received_mw (per link): the amplitudes are scaled so that each link's ray powers sum to it;
    direct_gain (per link, power ratio <= 1): then applied to the rays of the first cluster
    (the direct path through the walls). Neither changes the random draws."""
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
    first_cluster = cluster == 0
    decay = np.full(len(link), float(model["ray_decay_ns"]))
    if model.get("diffuse_first_cluster", False):
        decay[first_cluster] = model["first_cluster_decay_ns"]
    l1, l2 = model["ray_rate_1_per_ns"], model["ray_rate_2_per_ns"]
    n_rays = int(RAY_SPAN * decay.max() * max(l1, l2) * 1.3) + 10
    tau, counts = _ray_delays(rng, len(link), n_rays, model["ray_mixture_beta"], l1, l2, RAY_SPAN * decay)
    mean_power = _mean_ray_power(model, omega[link, cluster], decay, first_cluster, tau, counts)

    m = np.exp(rng.normal(model["nakagami_m0"], model["nakagami_sigma_m0"], len(tau)))
    np.maximum(m, 0.5, out=m)
    if model.get("first_ray_m") is not None:
        m[np.cumsum(counts) - counts] = model["first_ray_m"]   # the first ray of each cluster
    power = rng.gamma(m, np.divide(mean_power, m, out=mean_power))
    phase = rng.uniform(0.0, 2 * np.pi, len(tau))
    magnitude = np.sqrt(power, out=power)
    amplitudes = np.empty(len(tau), dtype=complex)
    trig = np.cos(phase, out=m)                            # m is used up: its buffer takes cos, then sin
    np.multiply(magnitude, trig, out=amplitudes.real)
    np.multiply(magnitude, np.sin(phase, out=trig), out=amplitudes.imag)
    delays = np.add(np.repeat(cluster_t[link, cluster], counts), tau, out=tau)
    ray_link = np.repeat(link, counts)
    if received_mw is not None:
        energy = np.bincount(ray_link, weights=magnitude**2, minlength=n_links)
        amplitudes *= np.sqrt(np.asarray(received_mw, dtype=float) / energy)[ray_link]
    if direct_gain is not None:
        direct = np.repeat(first_cluster, counts)
        amplitudes[direct] *= np.sqrt(np.asarray(direct_gain, dtype=float))[ray_link[direct]]
    return ray_link, delays, amplitudes


def tap_powers(link: np.ndarray, delays: np.ndarray, amplitudes: np.ndarray, tap_ns: float,
               n_links: int) -> np.ndarray:
    """Coherent sum of the rays falling into each receiver tap: |h_tap|^2, shape (n_links, taps)."""
    index = np.floor(delays / tap_ns).astype(int)
    n_taps = int(index.max()) + 1
    flat = link * n_taps + index
    real = np.bincount(flat, weights=amplitudes.real, minlength=n_links * n_taps)
    imag = np.bincount(flat, weights=amplitudes.imag, minlength=n_links * n_taps)
    return (real**2 + imag**2).reshape(n_links, n_taps)


def detect_delay_ns(powers: np.ndarray, tap_ns: float, detector: str, threshold_db: float,
                    noise_threshold: float | None = None) -> np.ndarray:
    """Delay (ns) of the tap a detector picks in each row of `powers` (links, taps): leading
    edge (first_path: first tap with power >= max(peak * 10^(-threshold_db / 10),
    noise_threshold)) or peak (strongest_path); NaN in a row whose peak is below
    `noise_threshold` (same unit as powers; None: no noise reference)."""
    check_detector(detector)
    powers = np.atleast_2d(powers)
    peak = np.argmax(powers, axis=1)
    peak_power = powers[np.arange(len(powers)), peak]
    if detector == "strongest_path":
        delay = peak * tap_ns
    else:
        floor = peak_power * 10 ** (-threshold_db / 10)
        if noise_threshold is not None:
            floor = np.maximum(floor, noise_threshold)
        delay = np.argmax(powers >= floor[:, None], axis=1) * tap_ns
    if noise_threshold is None:
        return delay
    return np.where(peak_power >= noise_threshold, delay, np.nan)


def detected_delays_ns(model: dict, rng: np.random.Generator, n_links: int, tap_ns: float, detector: str,
                       threshold_db: float, received_mw: np.ndarray | None = None,
                       direct_gain: np.ndarray | None = None, noise_threshold_mw: float | None = None) -> np.ndarray:
    """Excess delay (ns) the detector reports on `n_links` independent links of one channel
    model, in batches of LINKS_PER_BATCH links; NaN where nothing reaches the noise-referenced
    threshold. received_mw, direct_gain (per link) and noise_threshold_mw (the tap power a
    path needs, mW): the link budget (impulse_responses, detect_delay_ns); None: none."""
    check_detector(detector)
    out = [np.empty(0)]
    for start in range(0, n_links, LINKS_PER_BATCH):
        size = min(LINKS_PER_BATCH, n_links - start)
        part = slice(start, start + size)
        link, delays, amplitudes = impulse_responses(
            model, rng, size, None if received_mw is None else received_mw[part],
            None if direct_gain is None else direct_gain[part])
        out.append(detect_delay_ns(tap_powers(link, delays, amplitudes, tap_ns, size), tap_ns, detector, threshold_db,
                                   noise_threshold_mw))
    return np.concatenate(out)
