"""ZigBee (IEEE 802.15.4, 2.4 GHz) received signal strength.

P(d) = P0 - 10 n log10(d / d0) - W L_wall + X_shadow + X_fast   [dBm]
with W the walls crossed, X_shadow ~ N(0, sigma_sh) spatially correlated along the
mobile's path and X_fast ~ N(0, sigma_fast) independent per packet.

Shadowing follows Gudmundson's exponential autocorrelation
E[X(s) X(s + D)] = sigma^2 exp(-|D| / d_c); along a path this is exactly the AR(1)
recursion X_k = rho_k X_{k-1} + sqrt(1 - rho_k^2) sigma e_k with rho_k = exp(-|s_k - s_{k-1}| / d_c),
drawn independently per anchor.
"""

from __future__ import annotations

import numpy as np


def correlated_shadowing(arc_length: np.ndarray, n_anchors: int, sigma_db: float,
                         decorrelation_m: float, rng: np.random.Generator) -> np.ndarray:
    """(N, n_anchors) shadowing in dB at successive path positions `arc_length` (m)."""
    step = np.abs(np.diff(arc_length, prepend=arc_length[:1]))
    rho = np.exp(-step / decorrelation_m)
    innovations = rng.normal(0.0, sigma_db, (len(arc_length), n_anchors))
    out = np.sqrt(1.0 - rho**2)[:, None] * innovations         # sqrt(1 - rho_k^2) sigma e_k, all k at once
    out[0] = innovations[0]
    rows = list(out)                                          # views of the rows of `out`
    for rho_k, previous, row in zip(rho[1:].tolist(), rows, rows[1:]):
        row += rho_k * previous                               # + rho_k X_{k-1} (a + b == b + a in floats)
    return out


def mean_rss_dbm(distance_m: np.ndarray, walls: np.ndarray, p0_dbm: float, d0_m: float,
                 exponent: float, wall_loss_db: float) -> np.ndarray:
    """Log-distance path loss with wall attenuation; d is floored at d0."""
    d = np.maximum(distance_m, d0_m)
    return p0_dbm - 10.0 * exponent * np.log10(d / d0_m) - walls * wall_loss_db
