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

import pandas as pd

from wsnloc import results
from wsnloc.analysis import setup_facts
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError
from wsnloc.estimators import batched
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import claims as claims_of
from wsnloc.experiments.sensitivity import BASELINE
from wsnloc.metrics import verdicts
from wsnloc.metrics.stats import mean_ci95
from wsnloc.metrics.tracking import cell_metrics, score

EXPERIMENT = "C"
INPUT_TABLES = ("ranges", "truth", "anchors", "imu_5hz")   # the processed tables a run needs (see load_runs)
MODELS = ("P", "PV", "PVA")
# The a-priori sigmas and the models they act on (P: p_sigma_m; PV: white acceleration;
# PVA: acceleration input noise and bias walk; the range sigma: all).
SIGMA_MODELS = {"range_sigma_m": MODELS, "p_sigma_m": ("P",), "pv_accel_sigma_mps2": ("PV",),
                "pva_accel_sigma_mps2": ("PVA",), "pva_bias_walk_sigma": ("PVA",)}


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


# detail columns -> results metric; sqrt(PCRB) and efficiency RMSE / sqrt(PCRB) per run
DETAIL_METRICS = {"median": "median_m", "p95": "p95_m", "max": "max_m", "sqrt_pcrb": "sqrt_pcrb_m",
                  "efficiency": "efficiency_ratio"}


def run_all(datas: list[RunData], settings: Settings, subsets: list[str], models=MODELS) -> list[pd.DataFrame]:
    """Estimates of the (given) motion models for each beacon subset, scored against truth, per
    run of `datas`; all runs x cells are stepped together (batched.cell_tracks), one frame per run."""
    cells = [(model, subset) for subset in subsets for model in models]
    params = [estimator_params(settings, model, subset) for model, subset in cells]
    tracks = batched.cell_tracks("ekf", [(data, p) for data in datas for p in params], where="experiments.paper_c")
    labels = {"model": [model for model, _ in cells], "subset": [subset for _, subset in cells]}
    return [score(batched.stacked(tracks[i * len(cells):(i + 1) * len(cells)], labels), data.table("truth"))
            for i, data in enumerate(datas)]


def run(data: RunData, settings: Settings, subsets: list[str], models=MODELS) -> pd.DataFrame:
    """run_all of one run."""
    return run_all([data], settings, subsets, models)[0]


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
        for metric, name in DETAIL_METRICS.items():
            if metric in sel:   # the bound columns: metrics written with the PCRB (analysis.filter_quality)
                out.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table="Table I detail",
                                                 row=model, column=f"{speed} {metric}", scenario=scenario_label,
                                                 metric=name))
    if scenario_label == settings.table_2_scenario:
        for subset in settings.table_2_subsets:
            for model in MODELS:
                sel = metrics[(metrics["subset"] == subset) & (metrics["model"] == model)]
                out.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table="Table II", row=subset,
                                                 column=model, scenario=scenario_label, metric="rmse_m",
                                                 paper_value=paper["table_2_rmse_m"].get(subset, {}).get(model)))
                for metric in ("sqrt_pcrb", "efficiency"):
                    if metric in sel:   # the bound of each cell (analysis.filter_quality)
                        out.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table="Table II detail",
                                                         row=subset, column=f"{model} {metric}",
                                                         scenario=scenario_label, metric=DETAIL_METRICS[metric]))
    return out


def claims(metrics: dict[str, pd.DataFrame], speeds: dict[str, str], settings: Settings) -> list[dict]:
    """Paper C's claims decided on per-run RMSE (experiments.claims): metrics[label] is a
    scenario's per-run metrics.csv, speeds[label] its speed ("20 cm/s").

    Models and beacon sets of one scenario share their runs (paired); speeds are different
    scenarios (independent runs, Welch interval).
    """
    def rmse(label, subset, model, metric="rmse"):
        return claims_of.runs_of(metrics[label], metric, subset=subset, model=model)

    order = [claims_of.paired(rmse(label, settings.table_1_subset, lo), rmse(label, settings.table_1_subset, hi), "<",
                              f"{speeds[label]}: {lo} - {hi}")
             for label in metrics for lo, hi in zip(MODELS, MODELS[1:])]
    by_speed = sorted(metrics, key=lambda label: float(speeds[label].split()[0]))
    # speed on moving epochs only (metrics.tracking: rmse_moving): rests would mix the static share in
    speed = [claims_of.unpaired(rmse(slow, settings.table_1_subset, m, "rmse_moving"),
                                rmse(fast, settings.table_1_subset, m, "rmse_moving"), "<",
                                f"{m}: {speeds[slow]} - {speeds[fast]}, moving epochs (independent runs)")
             for m in MODELS for slow, fast in zip(by_speed, by_speed[1:])]
    beacons = []
    if settings.table_2_scenario in metrics:
        subsets = settings.table_2_subsets
        beacons = [claims_of.paired(rmse(settings.table_2_scenario, more, m), rmse(settings.table_2_scenario, fewer, m),
                                    "<", f"{m}: beacons {more} - {fewer}")
                   for m in MODELS for fewer, more in zip(subsets, subsets[1:])]
    return [claims_of.record("P < PV < PVA (Table I, every speed)", verdicts.claim(order)),
            claims_of.record("The error grows with speed (every model)", verdicts.claim(speed),
                             note="RMSE over the epochs at which the cart moves: "),
            claims_of.record("More beacons give a lower RMSE (Table II, every model)", verdicts.claim(beacons))]


def setup_rows(estimates: dict[str, pd.DataFrame], settings: Settings) -> list[dict]:
    """Set-up facts per scenario (analysis.setup_facts) on the P model with Table I's
    beacons: the static share of epochs and the beacons ranged per epoch."""
    rows = []
    for label, est in estimates.items():
        cell = _table_1(est, settings, "P")
        rows += [setup_facts.fact_row(EXPERIMENT, "static share of epochs", label, setup_facts.static_share(cell),
                                      "share"),
                 setup_facts.fact_row(EXPERIMENT, "beacons ranged per epoch", label,
                                      setup_facts.measurements_per_epoch(cell), "count")]
    return rows


MODEL_SIGMA = {"P": "p_sigma_m", "PV": "pv_accel_sigma_mps2", "PVA": "pva_accel_sigma_mps2"}


def noise_curves(grid: pd.DataFrame, settings: Settings) -> dict[str, pd.DataFrame]:
    """Table I RMSE (m) of each model against the factor applied to its own a-priori sigma
    (MODEL_SIGMA), from one scenario's sensitivity grid (experiments.sensitivity): per model
    a frame x (factor), value (mean over the sampled runs), ci95_low, ci95_high."""
    cell = grid[grid["subset"] == settings.table_1_subset]
    curves = {}
    for model, sigma in MODEL_SIGMA.items():
        own = cell[(cell["model"] == model) & ((cell["setting"] == BASELINE) | (cell["sigma"] == sigma))]
        points = [(factor, *mean_ci95(group["rmse"])) for factor, group in own.groupby("factor", sort=True)]
        if len(points) > 1:
            curves[f"{model} ({sigma})"] = pd.DataFrame(points, columns=["x", "value", "ci95_low", "ci95_high"])
    return curves


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
