"""UWB link budget: received power, receiver noise, link existence and the first-path threshold.

Received power of a link of distance d (m) under IEEE 802.15.4a channel model CM (CM3 office
LOS when no wall is crossed, CM4 office NLOS otherwise; Molisch et al., IEEE 802.15.4a channel
model final report, 2005):

    P_rx = P_tx - A_ant - PL0 - 10 n log10(max(d, d0) / d0) + sigma_S z      [dBm]

with z a unit-variance shadowing field along the mobile's path (Gudmundson: exponential
autocorrelation in the travelled distance, one field per anchor, sim.rss.correlated_shadowing),
so that the shadowing, the links it cuts and the first-path errors it causes are spatially
consistent instead of drawn anew at every ranging.

Receiver: thermal noise over the channel bandwidth plus the noise figure,

    N = 10 log10(k T0 B / 1 mW) + NF                                           [dBm],

and the channel impulse response the leading-edge detector reads is accumulated over the
preamble: N_sym symbols of duration T_sym add coherently, their noise incoherently, so a CIR
tap holding the share f of P_rx has SNR f P_rx / N * (B T_sym N_sym). A tap is detected when it
exceeds the noise by the detector's noise threshold (DW1000-class: a multiple of the noise
standard deviation of the accumulator), i.e. when its power reaches

    P_tap >= N - 10 log10(B T_sym N_sym) + NTM                                  [dBm].

A link exists (its frame is received) when P_rx >= the receiver's sensitivity; its range is
measured when at least one tap reaches the threshold above.
"""

from __future__ import annotations

import numpy as np

BOLTZMANN_J_PER_K = 1.380649e-23   # SI definition
REFERENCE_TEMPERATURE_K = 290.0    # T0 of the noise-figure definition (IEEE)


def thermal_noise_dbm(bandwidth_hz: float, noise_figure_db: float) -> float:
    """Receiver noise power kT0B + NF (dBm) over `bandwidth_hz`."""
    return 10.0 * np.log10(BOLTZMANN_J_PER_K * REFERENCE_TEMPERATURE_K * bandwidth_hz * 1e3) + noise_figure_db


def accumulation_gain_db(bandwidth_hz: float, symbol_ns: float, symbols: int) -> float:
    """SNR gain of a CIR tap accumulated over `symbols` preamble symbols of `symbol_ns` (ns):
    10 log10(B T_sym N_sym)."""
    return 10.0 * np.log10(bandwidth_hz * symbol_ns * 1e-9 * symbols)


def first_path_threshold_dbm(spec: dict) -> float:
    """Received power (dBm) a CIR tap needs to be detected as a path (radio.uwb of a campaign:
    bandwidth_mhz, noise_figure_db, preamble_symbol_ns, preamble_symbols, noise_threshold_db)."""
    bandwidth = spec["bandwidth_mhz"] * 1e6
    return thermal_noise_dbm(bandwidth, spec["noise_figure_db"]) \
        - accumulation_gain_db(bandwidth, spec["preamble_symbol_ns"], spec["preamble_symbols"]) \
        + spec["noise_threshold_db"]


def path_loss_db(distance_m: np.ndarray, model: dict, d0_m: float = 1.0) -> np.ndarray:
    """Mean path loss PL0 + 10 n log10(d / d0) (dB) of a channel model (path_loss_db_at_1m,
    path_loss_exponent); d is floored at d0."""
    d = np.maximum(np.asarray(distance_m, dtype=float), d0_m)
    return model["path_loss_db_at_1m"] + 10.0 * model["path_loss_exponent"] * np.log10(d / d0_m)


def received_power_dbm(spec: dict, distance_m: np.ndarray, nlos: np.ndarray, shadowing: np.ndarray) -> np.ndarray:
    """P_rx (dBm) of links of `distance_m`, CM4 where `nlos` else CM3, `shadowing` the unit
    shadowing field (scaled by each model's shadowing_sigma_db)."""
    out = np.empty(np.shape(distance_m))
    for name, mask in (("CM3", ~nlos), ("CM4", nlos)):
        model = spec["channel_models"][name]
        out[mask] = spec["tx_power_dbm"] - spec["antenna_loss_db"] - path_loss_db(distance_m[mask], model) \
            + model["shadowing_sigma_db"] * shadowing[mask]
    return out
