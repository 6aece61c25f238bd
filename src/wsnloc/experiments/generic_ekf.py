"""The PV EKF of paper A on any dataset (generic format included): ranges, and ranges + RSS
where the dataset has RSS. Anchors come from each run's own anchors table; with anchor
heights and the campaign's tag height, ranges are modelled in 3-D. The RSS model is
fitted on another run of the experiment (cyclically over all its runs, so a single-run
scenario is calibrated on another scenario's run); one run alone uses the configured model.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.experiments.ekf_tracking import run_ekf
from wsnloc.experiments.epochs import Epoch, build_epochs, score
from wsnloc.experiments.calibration import calibrate
from wsnloc.experiments.paper_d import preliminary_filter
from wsnloc.filters.measurement_models import RangeModel, RssModel, Stacked
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.geometry.lateration import multilateration
from wsnloc.metrics.stats import error_summary

EXPERIMENT = "generic"
VARIANTS = {"ranges": "PV EKF, ranges", "ranges+rss": "PV EKF, ranges + RSS"}


def calibrations(runs: dict[str, tuple[dict, Campaign]], configured: dict) -> dict[str, dict]:
    """RSS model per run key, fitted on the next run (cyclically) that has RSS and truth."""
    keys = [k for k, (t, _) in runs.items() if len(t["rss"]) and len(t["truth"])]
    out = {}
    for key in runs:
        others = [k for k in keys if k != key]
        if not others:
            out[key] = dict(configured, source="configured")
            continue
        donor = others[(keys.index(key) if key in keys else 0) % len(others)]
        tables, campaign = runs[donor]
        out[key] = dict(calibrate(tables["rss"], tables["truth"], campaign, configured.get("d0_m", 1.0),
                                  tables["anchors"]),
                        source=f"fitted on {donor}")
    return out


def run(tables: dict, campaign: Campaign, spec: dict, rss_model: dict) -> pd.DataFrame:
    anchors = tables["anchors"].set_index("anchor_id")
    xy = {a: anchors.loc[a, ["x", "y"]].to_numpy(float) for a in anchors.index}
    tag = campaign.tag_height_m
    dz = {a: (float(anchors.loc[a, "z"]) - tag) if tag is not None and np.isfinite(anchors.loc[a, "z"]) else 0.0
          for a in anchors.index}
    ranges = preliminary_filter(tables["ranges"], spec["max_range_m"])
    epochs = build_epochs(ranges, tables["rss"][np.isfinite(tables["rss"]["rss_dbm"])], spec["epoch_s"])
    F, Q = constant_velocity(spec["epoch_s"], spec["accel_sigma_mps2"])
    P0 = np.diag([spec["initial_sigma_m"] ** 2] * 2 + [spec["initial_speed_sigma_mps"] ** 2] * 2)

    def range_model(epoch: Epoch):
        return RangeModel(np.array([xy[a] for a in epoch.range_ids]).reshape(-1, 2),
                          np.full(len(epoch.ranges), spec["range_sigma_m"]),
                          np.array([dz[a] for a in epoch.range_ids]))

    def measure(epoch: Epoch, with_rss: bool):
        parts, z = [], []
        if len(epoch.ranges):
            parts.append(range_model(epoch))
            z.append(epoch.ranges)
        if with_rss and len(epoch.rss):
            parts.append(RssModel(np.array([xy[a] for a in epoch.rss_ids]), rss_model["p0_dbm"],
                                  rss_model["path_loss_exponent"], rss_model["sigma_db"], rss_model.get("d0_m", 1.0)))
            z.append(epoch.rss)
        return Stacked(parts, np.concatenate(z)) if parts else None

    def initial_fix(epoch: Epoch):
        if len(epoch.ranges) < 3:
            return None
        horizontal = np.sqrt(np.maximum(epoch.ranges**2 - np.array([dz[a] for a in epoch.range_ids]) ** 2, 0.0))
        return multilateration(np.array([xy[a] for a in epoch.range_ids]), horizontal)

    frames = []
    for variant in VARIANTS:
        with_rss = variant == "ranges+rss"
        if with_rss and len(tables["rss"]) == 0:
            continue
        track = run_ekf(epochs, F, Q, P0, [measure(epoch, with_rss) for epoch in epochs], initial_fix)
        frames.append(track.assign(variant=VARIANTS[variant]))
    return score(pd.concat(frames, ignore_index=True), tables["truth"]) if frames else pd.DataFrame()


def results_rows(metrics: pd.DataFrame, scenario: str) -> list[dict]:
    out = []
    for variant, group in metrics.groupby("variant", sort=False):
        for metric in ("rmse", "median", "p75", "p95", "max"):
            out.append(results.row_over_runs(group[metric], experiment=EXPERIMENT, table="EKF on datasets",
                                             row=variant, column=metric, scenario=scenario, metric=f"{metric}_m"))
    return out


def run_metrics(estimates: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for variant, group in estimates.groupby("variant", sort=False):
        stats = error_summary(group["error_m"])
        rows.append({"variant": variant, **{k: stats[k] for k in ("rmse", "median", "p75", "p95", "max")}})
    return pd.DataFrame(rows)
