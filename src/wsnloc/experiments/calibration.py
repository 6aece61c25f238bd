"""Calibrated RSS path-loss models and range biases: fitted on another run with truth, or configured.

No run is evaluated with a model fitted on its own data.
"""

from __future__ import annotations

import math
from typing import Callable

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError
from wsnloc.metrics.ranging import (fit_path_loss, fit_path_loss_per_anchor, fit_range_bias, fit_tdoa_bias,
                                    range_errors, rss_with_distance, tdoa_with_distances)
from wsnloc.metrics.tracking import run_metrics, score


def calibrate(rss: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign, d0_m: float,
              anchors: pd.DataFrame | None = None) -> dict:
    """P0, n and sigma fitted on one run with ground truth (all links, walls included).

    `anchors`: the run's own anchors table (generic datasets); default the campaign's.
    """
    samples = rss_with_distance(rss, truth, campaign, anchors)
    fit = fit_path_loss(samples["rss_dbm"], samples["true_distance_m"], d0_m)
    return {"p0_dbm": fit["P0_dBm"], "path_loss_exponent": fit["n"], "sigma_db": fit["sigma_dB"], "d0_m": d0_m}


def donor_rss_model(rss: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign, d0_m: float, prior_exponent: float,
                    track: Callable[[dict], pd.DataFrame], anchors: pd.DataFrame | None = None) -> dict:
    """The RSS model a donor run with truth gives the tracked runs of its site: per-receiver P0
    offsets (metrics.ranging.fit_path_loss_per_anchor; `p0_offsets_db`, applied by
    estimators.measurements.RssParams) and the exponent chosen on the donor by what it is for.

    The donor's own exponent fit is evidence, not the answer: on a walk the fitted n follows the
    path's geometry and the shadowing met on it (indoors the mean RSS flattens far from a
    receiver), and a model that predicts the donor's RSS best need not localise best. So two
    candidates, each with the donor's per-receiver P0s and sigma refitted under its exponent:
    the donor's fitted n and the configured prior n (`prior_exponent`); `track(model)` runs the
    estimator on the donor with the candidate, and the one with the lower RMSE on the donor's
    truth is kept (ties: the prior). The candidates share every other parameter, so the donor
    scores one number, its exponent. A candidate without a finite RMSE on the donor (no estimate,
    or none inside the truth's time span) cannot win: it is named "not scored" in the text, and with
    neither scored the prior is kept and the text says so. Returns the registry's RSS model
    (RSS_MODEL) with `p0_offsets_db`, `exponent_source` ("prior" or "donor fit") and
    `exponent_choice` (text: both candidates' donor RMSE).
    """
    samples = rss_with_distance(rss, truth, campaign, anchors)
    candidates = {}
    for label, exponent in (("prior", prior_exponent), ("donor fit", None)):
        fit = fit_path_loss_per_anchor(samples["rss_dbm"], samples["true_distance_m"], samples["anchor_id"], d0_m,
                                       exponent)
        model = {"p0_dbm": fit["P0_dBm"], "path_loss_exponent": fit["n"], "sigma_db": fit["sigma_dB"], "d0_m": d0_m,
                 "p0_offsets_db": fit["offsets_dB"]}
        estimates = track(model)
        error = float(run_metrics(score(estimates, truth), truth)["rmse"]) if len(estimates) else float("nan")
        candidates[label] = (error if math.isfinite(error) else math.inf, model)
    chosen = min(candidates, key=lambda k: candidates[k][0])      # "prior" first: kept on a tie
    text = "; ".join(f"{k} n={m['path_loss_exponent']:.2f}: " + (f"donor RMSE {e:.2f} m" if math.isfinite(e) else
                     "not scored (no estimate within the donor's truth)") for k, (e, m) in candidates.items())
    if not any(math.isfinite(e) for e, _ in candidates.values()):
        text += "; neither candidate scored: the prior kept untested"
    return dict(candidates[chosen][1], exponent_source=chosen, exponent_choice=f"{chosen} ({text})")


def donor_model_for(p: dict, rss: pd.DataFrame, truth: pd.DataFrame, campaign: Campaign,
                    track: Callable[[dict], pd.DataFrame], anchors: pd.DataFrame | None = None) -> dict:
    """The RSS model a donor gives by the registry's `rss_calibration` in p: `other_run`
    donor_rss_model (per-receiver P0s, the exponent chosen by `track` on the donor),
    `other_run_common` calibrate (one P0, n and sigma by least squares: the papers' protocol)."""
    d0 = p.get("d0_m", 1.0)
    if p.get("rss_calibration") == "other_run_common":
        return calibrate(rss, truth, campaign, d0, anchors)
    return donor_rss_model(rss, truth, campaign, d0, p["path_loss_exponent"], track, anchors)


RSS_MODEL = ("p0_dbm", "path_loss_exponent", "sigma_db", "d0_m")   # the registry's RSS model parameters


def rss_models_for_runs(run_tables: dict[str, dict], campaign: Campaign, members: list[str],
                        p: dict) -> dict[str, dict]:
    """The RSS model each run is evaluated with, by a cell's registry parameters p.

    rss_calibration `other_run_common`: one P0, n, sigma fitted (calibrate) on the next run
    (cyclically) with its truth, the papers' protocol (papers A and D, the static-share and PL0
    analyses use it); `configured`: p's model (RSS_MODEL). With a single run the donor falls back
    to p's model. `other_run` (per-receiver P0s, the exponent chosen by tracking the donor) needs
    the estimator on the donor: donor_model_for, as studies and `wsnloc estimate` call it; here it
    is refused (it was silently fitted as other_run_common).
    """
    method, configured = p["rss_calibration"], {k: p[k] for k in RSS_MODEL}
    if method == "other_run":
        raise ConfigError("config key 'rss_calibration': other_run (per-receiver P0s, exponent chosen by tracking "
                          "the donor) is not available to the papers' per-scenario calibration; use "
                          "other_run_common (one P0, n, sigma fitted on the next run) or configured")
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
