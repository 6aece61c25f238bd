"""Paper C (Rafi ullah Khan et al. 2014): EKF with P, PV and PVA motion models on Cricket
ultrasound ranges, at 20/40/60 cm/s and with 3, 4 or 6 beacons.

Every cell is the registry's `ekf` estimator with the P, PV or PVA motion model, one
update per estimation period: Cricket beacons range one at a time at random instants,
the ranges of one period are grouped (several ranges to one beacon averaged), so all
three models see the same measurements. The PVA model takes the measured acceleration
as input (estimators.inertial.floor_input: the 5 Hz IMU's horizontal specific force,
bias at rest removed, rotated with the gyro heading from the known start pose). This
module holds only the paper's table layout, its claims and figures.
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

EXPERIMENT = "C"
INPUT_TABLES = ("ranges", "truth", "anchors", "imu_5hz")   # the processed tables a run needs (see load_runs)
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


def estimator_params(settings: Settings, model: str, subset: str) -> dict:
    """Registry parameters of the `ekf` estimator for one motion model and beacon subset."""
    s = settings
    accel = {"P": s.pv_accel_sigma_mps2, "PV": s.pv_accel_sigma_mps2, "PVA": s.pva_accel_sigma_mps2}[model]
    return {"anchors": subset, "measurements": "toa", "motion": model.lower(), "update": "epoch",
            "epoch_s": s.epoch_s, "preliminary_filter": True, "max_range_m": s.max_range_m,
            "range_sigma_m": s.range_sigma_m, "p_sigma_m": s.p_sigma_m, "accel_sigma_mps2": accel,
            "bias_walk_sigma": s.pva_bias_walk_sigma, "initial_sigma_m": s.initial_sigma_m,
            "initial_speed_sigma_mps": s.initial_speed_sigma_mps, "initial_bias_sigma_mps2": s.initial_bias_sigma_mps2,
            "static_start_s": s.static_bias_s}


def run(data: RunData, settings: Settings, subsets: list[str]) -> pd.DataFrame:
    """Estimates of the three models for each beacon subset, scored against truth."""
    cells = [(model, subset) for subset in subsets for model in MODELS]
    tracks = batched.run_rows("ekf", data, [estimator_params(settings, model, subset) for model, subset in cells],
                              where="experiments.paper_c")
    frames = [track.assign(model=model, subset=subset) for track, (model, subset) in zip(tracks, cells)]
    return score(pd.concat(frames, ignore_index=True), data.table("truth"))


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    return cell_metrics(estimates, ["subset", "model"], truth)


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


def subsets_of(settings: Settings, label: str) -> list[str]:
    """Beacon subsets run on one scenario: Table I's, plus Table II's on its scenario."""
    subsets = settings.table_2_subsets if label == settings.table_2_scenario else []
    return list(dict.fromkeys(list(subsets) + [settings.table_1_subset]))


def _table_1(est: pd.DataFrame, settings: Settings, model: str) -> pd.DataFrame:
    return est[(est["model"] == model) & (est["subset"] == settings.table_1_subset)]


def cdf_panels(estimates: dict[str, pd.DataFrame], settings: Settings) -> dict:
    """Error samples (all runs) per scenario and model, Table I's beacons."""
    return {label: {m: _table_1(est, settings, m)["error_m"].to_numpy() for m in MODELS}
            for label, est in estimates.items()}


def histogram_panels(estimates: dict[str, pd.DataFrame], settings: Settings) -> dict:
    """Errors of each model on Table II's scenario (the paper's Fig. 4b)."""
    est = estimates.get(settings.table_2_scenario)
    if est is None:
        return {}
    return {f"{m} ({settings.table_2_scenario})": _table_1(est, settings, m)["error_m"] for m in MODELS}


def trajectory_panels(estimates: dict[str, pd.DataFrame], settings: Settings) -> dict:
    """First run of Table II's scenario: truth and the three models' tracks."""
    est = estimates.get(settings.table_2_scenario)
    if est is None:
        return {}
    first = est[est["run"] == est["run"].iloc[0]]
    truth = _table_1(first, settings, "P")[["true_x", "true_y"]].rename(columns={"true_x": "x", "true_y": "y"})
    return {f"{settings.table_2_scenario}, {first['run'].iloc[0]}": (truth, {m: _table_1(first, settings, m)
                                                                          for m in MODELS})}
