"""Calibrated RSS path-loss models and range biases: fitted on another run with truth, or configured.

No run is evaluated with a model fitted on its own data.
"""

from __future__ import annotations

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.metrics.ranging import (fit_path_loss, fit_range_bias, fit_tdoa_bias, range_errors, rss_with_distance,
                                    tdoa_with_distances)


def calibrate(rss: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign, d0_m: float,
              anchors: pd.DataFrame | None = None) -> dict:
    """P0, n and sigma fitted on one run with ground truth (all links, walls included).

    `anchors`: the run's own anchors table (generic datasets); default the campaign's.
    """
    samples = rss_with_distance(rss, truth, campaign, anchors)
    fit = fit_path_loss(samples["rss_dbm"], samples["true_distance_m"], d0_m)
    return {"p0_dbm": fit["P0_dBm"], "path_loss_exponent": fit["n"], "sigma_db": fit["sigma_dB"], "d0_m": d0_m}


RSS_MODEL = ("p0_dbm", "path_loss_exponent", "sigma_db", "d0_m")   # the registry's RSS model parameters


def rss_models_for_runs(run_tables: dict[str, dict], campaign: Campaign, members: list[str],
                        p: dict) -> dict[str, dict]:
    """The RSS model each run is evaluated with, by a cell's registry parameters p.

    rss_calibration `other_run`: fitted on the next run (cyclically) with its truth;
    `configured`: p's model (RSS_MODEL). With a single run `other_run` falls back to p's model.
    """
    method, configured = p["rss_calibration"], {k: p[k] for k in RSS_MODEL}
    names = list(run_tables)
    if method == "configured" or len(names) < 2:
        return {name: dict(configured, source="configured") for name in names}
    fitted = {name: calibrate(t["rss"][t["rss"]["anchor_id"].isin(members)], t["truth"], campaign,
                              configured.get("d0_m", 1.0)) for name, t in run_tables.items()}
    return {name: dict(fitted[names[(i + 1) % len(names)]], source=f"fitted on {names[(i + 1) % len(names)]}")
            for i, name in enumerate(names)}


def calibrate_ranges(ranges: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign,
                     anchors: pd.DataFrame | None = None) -> dict:
    """Range scale and per-anchor offsets (metrics.ranging.fit_range_bias) fitted on one run
    with ground truth: valid ranges (status 0) against the true (3-D) distance, all links."""
    samples = range_errors(ranges, truth, campaign, anchors)
    return fit_range_bias(samples["range_m"], samples["true_distance_m"], samples["anchor_id"])


def calibrate_tdoa(tdoa: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign,
                   anchors: pd.DataFrame | None = None) -> dict:
    """Range scale and per-anchor offsets (relative to the most frequent reference anchor;
    metrics.ranging.fit_tdoa_bias) fitted on the range differences of one run with ground
    truth: the true (3-D) distance of each pair's two anchors at its time."""
    samples = tdoa_with_distances(tdoa, truth, campaign, anchors)
    return fit_tdoa_bias(samples["tdoa_m"], samples["true_distance_m"], samples["true_ref_distance_m"],
                         samples["anchor_id"], samples["ref_anchor_id"])
