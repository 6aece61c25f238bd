"""Paper A (Khan, Sottile, Spirito 2013): EKF with the PV model on UWB TOA ranges, ZigBee
RSS, or both stacked (hybrid), without (Table I) and with (Table II) accelerometer motion
detection, on the Newcom++ scenarios.

Each row (measurement type + anchor subsets) is the registry's `ekf` estimator (PV model,
one update per epoch of `epoch_s`), run without and with motion detection; the RSS model
P0, n, sigma is calibrated on another run with truth (the caller's RunData.rss_model).
This module holds only the paper's table layout, its claims and figures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError
from wsnloc.estimators import batched
from wsnloc.estimators.run_data import RunData
from wsnloc.metrics.tracking import cell_metrics, score

EXPERIMENT = "A"
INPUT_TABLES = ("ranges", "rss", "imu", "truth", "anchors")   # the processed tables a run needs (see load_runs)
MEASUREMENT_LABEL = {"toa": "distance (UWB)", "rss": "RSS (ZigBee)", "hybrid": "hybrid"}


def row_label(row: dict) -> str:
    anchors = ", ".join(row[k] for k in ("uwb", "zigbee") if k in row)
    return f"{MEASUREMENT_LABEL[row['measurements']]} | {anchors}"


@dataclass
class Settings:
    epoch_s: float
    rows: list
    uwb_preliminary_filter: bool
    max_range_m: float
    range_sigma_m: float
    rss_calibration: str
    rss_model: dict
    accel_sigma_mps2: float
    initial_sigma_m: float
    initial_speed_sigma_mps: float
    motion_threshold_mps2: float
    static_reference_s: float

    @classmethod
    def from_config(cls, spec: dict) -> "Settings":
        return cls(**{k: spec[k] for k in cls.__dataclass_fields__})

    def check_against(self, campaign: Campaign) -> None:
        subsets = campaign.spec.get("subsets", {})
        for i, row in enumerate(self.rows):
            for key in ("uwb", "zigbee"):
                if key in row and row[key] not in subsets:
                    raise ConfigError(f"config key 'experiments.paper_a.rows.{i}.{key}': no subset {row[key]!r} "
                                      f"in {campaign.source}")
            needed = {"toa": ["uwb"], "rss": ["zigbee"], "hybrid": ["uwb", "zigbee"]}[row["measurements"]]
            for key in needed:
                if key not in row:
                    raise ConfigError(f"config key 'experiments.paper_a.rows.{i}.{key}': required for "
                                      f"{row['measurements']} measurements")


def estimator_params(settings: Settings, row: dict, motion_detection: bool) -> dict:
    """Registry parameters of the `ekf` estimator for one row of Table I (or II, with motion detection)."""
    return {
        "anchors": "+".join(row[k] for k in ("uwb", "zigbee") if k in row),
        "measurements": row["measurements"], "motion": "pv", "update": "epoch", "epoch_s": settings.epoch_s,
        "preliminary_filter": settings.uwb_preliminary_filter, "max_range_m": settings.max_range_m,
        "range_sigma_m": settings.range_sigma_m, "accel_sigma_mps2": settings.accel_sigma_mps2,
        "initial_sigma_m": settings.initial_sigma_m, "initial_speed_sigma_mps": settings.initial_speed_sigma_mps,
        "motion_detection": motion_detection, "motion_threshold_mps2": settings.motion_threshold_mps2,
        "static_start_s": settings.static_reference_s, "rss_calibration": settings.rss_calibration,
        "p0_dbm": settings.rss_model["p0_dbm"], "path_loss_exponent": settings.rss_model["path_loss_exponent"],
        "sigma_db": settings.rss_model["sigma_db"], "d0_m": settings.rss_model.get("d0_m", 1.0),
    }


def run(data: RunData, settings: Settings) -> pd.DataFrame:
    """Estimates of every row, without (Table I) and with (Table II) motion detection, scored."""
    cells = [(row, table, motion_detection) for row in settings.rows
             for table, motion_detection in (("Table I", False), ("Table II", True))]
    tracks = batched.run_rows("ekf", data, [estimator_params(settings, row, md) for row, _, md in cells],
                              where="experiments.paper_a")
    frames = [track.assign(row=row_label(row), table=table) for track, (row, table, _) in zip(tracks, cells)]
    return score(pd.concat(frames, ignore_index=True), data.table("truth"))


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per (table, row): the standard run metrics (metrics.tracking) and the mean NIS."""
    metrics = cell_metrics(estimates, ["table", "row"], truth)
    metrics["nis_mean"] = estimates.groupby(["table", "row"], sort=False)["nis"].mean().to_numpy()
    return metrics


def paper_value(paper: dict, row: dict, table: str, motion: str):
    for published in paper["rmse_m"]:
        anchors = ", ".join(row[k] for k in ("uwb", "zigbee") if k in row)
        if published["row"] == MEASUREMENT_LABEL[row["measurements"]] and published["anchors"] == anchors:
            return published[f"{'I' if table == 'Table I' else 'II'}_{motion}"]
    return None


def results_rows(metrics: pd.DataFrame, scenario: str, motion: str, settings: Settings, paper: dict) -> list[dict]:
    out = []
    for table in ("Table I", "Table II"):
        for row in settings.rows:
            sel = metrics[(metrics["table"] == table) & (metrics["row"] == row_label(row))]
            out.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table=table, row=row_label(row),
                                             column=motion, scenario=scenario, metric="rmse_m",
                                             paper_value=paper_value(paper, row, table, motion)))
            for metric in ("median", "p95", "max"):
                out.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table=f"{table} detail",
                                                 row=row_label(row), column=metric, scenario=scenario,
                                                 metric=f"{metric}_m"))
    return out


def claims(res: pd.DataFrame, settings: Settings) -> list[dict]:
    sel = res[(res["experiment"] == EXPERIMENT) & (res["metric"] == "rmse_m") & res["table"].isin(["Table I", "Table II"])]
    value = {(r.table, r.row, r.column): r.value for r in sel.itertuples()}
    motions = sorted(sel["column"].unique())
    labels = [row_label(r) for r in settings.rows]
    by_kind = {kind: [row_label(r) for r in settings.rows if r["measurements"] == kind] for kind in MEASUREMENT_LABEL}
    out = []

    def check(text, cases):
        out.append({"claim": text, "holds": bool(cases) and all(ok for ok, _ in cases),
                    "evidence": "; ".join(e for _, e in cases)})

    cases = []
    for table in ("Table I", "Table II"):
        for motion in motions:
            for hybrid, toa, rss in zip(by_kind["hybrid"], by_kind["toa"], by_kind["rss"]):
                h, t, r = (value.get((table, x, motion), np.nan) for x in (hybrid, toa, rss))
                cases.append((h < t < r, f"{table} {motion}: hybrid {h:.3f} < TOA {t:.3f} < RSS {r:.3f}?"))
    check("Hybrid beats TOA-only, which beats RSS-only", cases)

    cases = []
    for table in ("Table I", "Table II"):
        for motion in motions:
            for kind, rows in by_kind.items():
                if len(rows) == 2:
                    more, fewer = (value.get((table, x, motion), np.nan) for x in rows)
                    cases.append((more < fewer, f"{table} {motion} {kind}: {rows[0]} {more:.3f} vs {rows[1]} {fewer:.3f}"))
    check("More anchors give a lower RMSE", cases)

    cases = []
    if {"constant", "variable"} <= set(motions):
        for table in ("Table I", "Table II"):
            for label in labels:
                c, v = value.get((table, label, "constant"), np.nan), value.get((table, label, "variable"), np.nan)
                cases.append((c < v, f"{table} {label}: constant {c:.3f} vs variable {v:.3f}"))
    check("Constant speed is tracked better than variable speed", cases)

    cases = []
    for motion in motions:
        for label in labels:
            plain, md = value.get(("Table I", label, motion), np.nan), value.get(("Table II", label, motion), np.nan)
            cases.append((md < plain, f"{motion} {label}: {plain:.3f} -> {md:.3f} with motion detection"))
    check("Motion detection improves every row", cases)
    return out


def cdf_panels(estimates: dict[str, pd.DataFrame]) -> dict:
    """Error samples (all runs) per scenario: each row of Table I and the hybrid row of Table II."""
    panels = {}
    for label, est in estimates.items():
        curves = {f"{row} (I)": est[(est["table"] == "Table I") & (est["row"] == row)]["error_m"].to_numpy()
                  for row in est["row"].unique()}
        first_hybrid = next((r for r in est["row"].unique() if r.startswith("hybrid")), None)
        if first_hybrid:
            curves[f"{first_hybrid} (II, motion detection)"] = est[(est["table"] == "Table II")
                                                                   & (est["row"] == first_hybrid)]["error_m"].to_numpy()
        panels[label] = curves
    return panels


def anchor_curves(res: pd.DataFrame, settings: Settings) -> dict:
    """Table I RMSE against the number of anchors, per measurement type and scenario."""
    sel = res[(res["experiment"] == EXPERIMENT) & (res["table"] == "Table I") & (res["metric"] == "rmse_m")]
    curves = {}
    for row in settings.rows:
        count = sum(int(row[k].split("=")[1]) for k in ("uwb", "zigbee") if k in row)
        for r in sel[sel["row"] == row_label(row)].itertuples():
            key = f"{MEASUREMENT_LABEL[row['measurements']]}, {r.column}"
            curves.setdefault(key, ([], []))
            curves[key][0].append(count)
            curves[key][1].append(r.value)
    return {k: tuple(map(list, zip(*sorted(zip(*v))))) for k, v in curves.items()}


def trajectory_panels(estimates: dict[str, pd.DataFrame]) -> dict:
    """First run of each scenario: truth and the first TOA, RSS and hybrid rows (Table I), hybrid (Table II)."""
    panels = {}
    for label, est in estimates.items():
        first = est[est["run"] == est["run"].iloc[0]]
        rows = list(dict.fromkeys(first["row"]))
        picks = [(r, "Table I") for r in (next((x for x in rows if x.startswith(k)), None)
                                          for k in ("distance", "RSS", "hybrid")) if r]
        picks += [(next((x for x in rows if x.startswith("hybrid")), rows[0]), "Table II")]
        tracks = {f"{r} ({t[6:]})": first[(first["row"] == r) & (first["table"] == t)] for r, t in picks}
        truth = next(iter(tracks.values()))[["true_x", "true_y"]].rename(columns={"true_x": "x", "true_y": "y"})
        panels[f"{label}, {first['run'].iloc[0]}"] = (truth, tracks)
    return panels
