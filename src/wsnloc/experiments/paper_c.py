"""Paper C (Rafi ullah Khan et al. 2014): EKF with P, PV and PVA motion models on Cricket
ultrasound ranges, at 20/40/60 cm/s and with 3, 4 or 6 beacons.

Cricket beacons range one at a time at random instants; the ranges of one estimation
period are grouped and applied in one update (several ranges to one beacon are
averaged), so all three models see the same measurements. The PVA model takes the
measured acceleration as input: the 5 Hz IMU's horizontal specific force, minus the
bias measured at rest, rotated to the floor with the gyro-integrated heading from the
known start pose, averaged over the period; the filter's bias states absorb the rest.
Beacon positions are the nominal (hand-measured) ones of the campaign file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError
from wsnloc.experiments.ekf_tracking import run_ekf
from wsnloc.experiments.epochs import Epoch, build_epochs, score
from wsnloc.filters.measurement_models import RangeModel, Stacked
from wsnloc.filters.motion_models import constant_velocity, position_only, pva
from wsnloc.geometry.lateration import multilateration
from wsnloc.inertial.dead_reckoning import floor_acceleration, static_bias
from wsnloc.io.tables import empty as empty_table
from wsnloc.metrics.stats import error_summary

EXPERIMENT = "C"
INPUT_TABLES = ("ranges", "truth")   # the processed tables a run needs (see load_runs)
MODELS = ("P", "PV", "PVA")


@dataclass
class Settings:
    epoch_s: float
    table_1_subset: str
    table_2_subsets: list
    table_2_scenario: str
    range_sigma_m: float
    max_range_m: float
    p_sigma_m: float
    pv_accel_sigma_mps2: float
    pva_accel_sigma_mps2: float
    pva_bias_walk_sigma: float
    initial_sigma_m: float
    initial_speed_sigma_mps: float
    initial_bias_sigma_mps2: float
    static_bias_s: float

    @classmethod
    def from_config(cls, spec: dict) -> "Settings":
        return cls(**{k: spec[k] for k in cls.__dataclass_fields__})

    def check_against(self, campaign: Campaign) -> None:
        subsets = campaign.spec.get("subsets", {})
        for key, name in [("table_1_subset", self.table_1_subset)] + \
                         [(f"table_2_subsets.{i}", s) for i, s in enumerate(self.table_2_subsets)]:
            if name not in subsets:
                raise ConfigError(f"config key 'experiments.paper_c.{key}': no subset {name!r} in {campaign.source}")


def model_matrices(name: str, settings: Settings):
    """(F, Q, P0, B) of one motion model for the estimation period."""
    dt, s = settings.epoch_s, settings
    if name == "P":
        F, Q = position_only(s.p_sigma_m)
        return F, Q, np.eye(2) * s.initial_sigma_m**2, None
    if name == "PV":
        F, Q = constant_velocity(dt, s.pv_accel_sigma_mps2)
        return F, Q, np.diag([s.initial_sigma_m**2] * 2 + [s.initial_speed_sigma_mps**2] * 2), None
    if name == "PVA":
        F, B, Q = pva(dt, s.pva_accel_sigma_mps2, s.pva_bias_walk_sigma)
        P0 = np.diag([s.initial_sigma_m**2] * 2 + [s.initial_speed_sigma_mps**2] * 2 + [s.initial_bias_sigma_mps2**2] * 2)
        return F, Q, P0, B
    raise ValueError(f"unknown motion model {name!r} (expected P, PV or PVA)")


def floor_input(imu_5hz: pd.DataFrame, campaign: Campaign, settings: Settings) -> pd.DataFrame:
    """Floor-frame acceleration (t, ax, ay) of a run: bias at rest removed, gyro heading from the start pose."""
    if len(imu_5hz) == 0:
        return pd.DataFrame({"t": [], "ax": [], "ay": []})
    return floor_acceleration(imu_5hz, campaign.path.start_pose()[2], static_bias(imu_5hz, settings.static_bias_s))


def epoch_inputs(acc: pd.DataFrame, times: np.ndarray) -> np.ndarray:
    """(len(times), 2) mean floor-frame acceleration over each period; NaN without IMU samples."""
    index = np.searchsorted(times, acc["t"].to_numpy(), side="left")
    valid = index < len(times)
    out = np.full((len(times), 2), np.nan)
    counts = np.bincount(index[valid], minlength=len(times))
    for j, column in enumerate(("ax", "ay")):
        sums = np.bincount(index[valid], weights=acc[column].to_numpy()[valid], minlength=len(times))
        with np.errstate(invalid="ignore", divide="ignore"):
            out[:, j] = sums / counts
    return out


def run(tables: dict, imu_5hz: pd.DataFrame, campaign: Campaign, settings: Settings, subsets: list[str]) -> pd.DataFrame:
    """Estimates of the three models for each beacon subset, scored against truth."""
    ranges = tables["ranges"]
    ranges = ranges[(ranges["status"] == 0) & np.isfinite(ranges["range_m"]) & (ranges["range_m"] > 0)
                    & (ranges["range_m"] <= settings.max_range_m)]
    no_rss = empty_table("rss")
    acc = floor_input(imu_5hz, campaign, settings)
    xy = {a: np.array([x, y]) for a, x, y in campaign.anchors[["anchor_id", "x", "y"]].itertuples(index=False)}
    frames = []
    for subset in subsets:
        members = set(campaign.spec["subsets"][subset])
        epochs = build_epochs(ranges[ranges["anchor_id"].isin(members)], no_rss, settings.epoch_s)
        inputs = epoch_inputs(acc, np.array([e.t for e in epochs]))

        def measure(epoch: Epoch):
            if len(epoch.ranges) == 0:
                return None
            anchors = np.array([xy[a] for a in epoch.range_ids])
            return Stacked([RangeModel(anchors, np.full(len(anchors), settings.range_sigma_m))], epoch.ranges)

        def initial_fix(epoch: Epoch):
            return multilateration(np.array([xy[a] for a in epoch.range_ids]).reshape(-1, 2), epoch.ranges)

        measurements = [measure(epoch) for epoch in epochs]
        for model in MODELS:
            F, Q, P0, B = model_matrices(model, settings)
            track = run_ekf(epochs, F, Q, P0, measurements, initial_fix, B=B, inputs=inputs if B is not None else None)
            frames.append(track.assign(model=model, subset=subset))
    return score(pd.concat(frames, ignore_index=True), tables["truth"])


def run_metrics(estimates: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (subset, model), group in estimates.groupby(["subset", "model"], sort=False):
        stats = error_summary(group["error_m"])
        rows.append({"subset": subset, "model": model, **{k: stats[k] for k in ("rmse", "median", "p95", "max")}})
    return pd.DataFrame(rows)


def speed_label(campaign: Campaign, scenario: str) -> str:
    return f"{campaign.section('scenarios', scenario)['speed_mps'] * 100:.0f} cm/s"


def results_rows(metrics: pd.DataFrame, scenario_label: str, speed: str, settings: Settings, paper: dict) -> list[dict]:
    out = []
    for model in MODELS:
        sel = metrics[(metrics["subset"] == settings.table_1_subset) & (metrics["model"] == model)]
        out.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table="Table I", row=model, column=speed,
                                         scenario=scenario_label, metric="rmse_m",
                                         paper_value=paper["table_1_rmse_m"].get(model, {}).get(speed)))
        for metric in ("median", "p95", "max"):
            out.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table="Table I detail", row=model,
                                             column=f"{speed} {metric}", scenario=scenario_label, metric=f"{metric}_m"))
    if scenario_label == settings.table_2_scenario:
        for subset in settings.table_2_subsets:
            for model in MODELS:
                sel = metrics[(metrics["subset"] == subset) & (metrics["model"] == model)]
                out.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table="Table II", row=subset,
                                                 column=model, scenario=scenario_label, metric="rmse_m",
                                                 paper_value=paper["table_2_rmse_m"].get(subset, {}).get(model)))
    return out


def claims(res: pd.DataFrame, speeds: list[str], settings: Settings) -> list[dict]:
    sel = res[(res["experiment"] == EXPERIMENT) & (res["metric"] == "rmse_m")]
    t1 = {(r.row, r.column): r.value for r in sel[sel["table"] == "Table I"].itertuples()}
    t2 = {(r.row, r.column): r.value for r in sel[sel["table"] == "Table II"].itertuples()}
    out = []

    def check(text, cases):
        out.append({"claim": text, "holds": bool(cases) and all(ok for ok, _ in cases),
                    "evidence": "; ".join(e for _, e in cases)})

    check("P < PV < PVA (Table I, every speed)",
          [(t1.get(("P", s), np.nan) < t1.get(("PV", s), np.nan) < t1.get(("PVA", s), np.nan),
            f"{s}: P {t1.get(('P', s), np.nan):.3f}, PV {t1.get(('PV', s), np.nan):.3f}, PVA {t1.get(('PVA', s), np.nan):.3f}")
           for s in speeds])
    check("The error grows with speed (every model)",
          [(all(t1.get((m, a), np.nan) < t1.get((m, b), np.nan) for a, b in zip(speeds, speeds[1:])),
            f"{m}: " + " -> ".join(f"{t1.get((m, s), np.nan):.3f}" for s in speeds)) for m in MODELS])
    subsets = settings.table_2_subsets
    check("More beacons give a lower RMSE (Table II, every model)",
          [(all(t2.get((a, m), np.nan) > t2.get((b, m), np.nan) for a, b in zip(subsets, subsets[1:])),
            f"{m}: " + " -> ".join(f"{t2.get((s, m), np.nan):.3f}" for s in subsets)) for m in MODELS])
    return out


def anchor_curves(res: pd.DataFrame, settings: Settings) -> dict:
    """Table II RMSE against the number of beacons, one line per model."""
    sel = res[(res["experiment"] == EXPERIMENT) & (res["table"] == "Table II") & (res["metric"] == "rmse_m")]
    curves = {}
    for model in MODELS:
        points = sorted((int(r.row.split(":")[0]), r.value) for r in sel[sel["column"] == model].itertuples())
        if points:
            curves[model] = ([p[0] for p in points], [p[1] for p in points])
    return curves
