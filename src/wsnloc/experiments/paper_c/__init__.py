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

import pandas as pd

from wsnloc import results
from wsnloc.analysis import setup_facts
from wsnloc.campaign import Campaign
from wsnloc.estimators import batched
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import cells, claims as claims_of
from wsnloc.experiments.sensitivity import BASELINE
from wsnloc.metrics import verdicts
from wsnloc.metrics.stats import mean_interval
from wsnloc.metrics.tracking import cell_metrics, score

PAPER = "paper_c"
EXPERIMENT = "C"
INPUT_TABLES = ("ranges", "truth", "anchors", "imu_5hz")   # the processed tables a run needs (see load_runs)
MODELS = cells.CELLS[PAPER]   # the paper's motion models P, PV, PVA: its cells (config estimators)


def cell_params(spec: dict, label: str, model: str, subset: str) -> dict:
    """Registry parameters of one motion model's cell with one beacon subset on scenario `label`."""
    return cells.params(spec, model, label, PAPER, {"anchors": subset})


# detail columns -> results metric; sqrt(PCRB) and efficiency RMSE / sqrt(PCRB) per run
DETAIL_METRICS = {"median": "median_m", "p95": "p95_m", "max": "max_m", "sqrt_pcrb": "sqrt_pcrb_m",
                  "efficiency": "efficiency_ratio"}


def run_all(datas: list[RunData], spec: dict, label: str, subsets: list[str], models=MODELS) -> list[pd.DataFrame]:
    """Estimates of the (given) motion models for each beacon subset, scored against truth, per
    run of `datas` (scenario `label`); all runs x cells are stepped together
    (batched.cell_tracks), one frame per run."""
    grid = [(model, subset) for subset in subsets for model in models]
    params = [cell_params(spec, label, model, subset) for model, subset in grid]
    tracks = batched.cell_tracks("ekf", [(data, p) for data in datas for p in params], where=cells.where(PAPER))
    labels = {"model": [model for model, _ in grid], "subset": [subset for _, subset in grid]}
    return [score(batched.stacked(tracks[i * len(grid):(i + 1) * len(grid)], labels), data.table("truth"))
            for i, data in enumerate(datas)]


def run(data: RunData, spec: dict, label: str, subsets: list[str], models=MODELS) -> pd.DataFrame:
    """run_all of one run."""
    return run_all([data], spec, label, subsets, models)[0]


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    return cell_metrics(estimates, ["subset", "model"], truth)


def speed_label(campaign: Campaign, scenario: str) -> str:
    return f"{campaign.section('scenarios', scenario)['speed_mps'] * 100:.0f} cm/s"


def results_rows(metrics: pd.DataFrame, scenario_label: str, speed: str, spec: dict, paper: dict) -> list[dict]:
    out = []
    for model in MODELS:
        sel = metrics[(metrics["subset"] == spec["table_1_subset"]) & (metrics["model"] == model)]
        out.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table="Table I", row=model, column=speed,
                                         scenario=scenario_label, metric="rmse_m",
                                         paper_value=paper["table_1_rmse_m"].get(model, {}).get(speed)))
        for metric, name in DETAIL_METRICS.items():
            if metric in sel:   # the bound columns: metrics written with the PCRB (analysis.filter_quality)
                out.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table="Table I detail",
                                                 row=model, column=f"{speed} {metric}", scenario=scenario_label,
                                                 metric=name))
    if scenario_label == spec["table_2_scenario"]:
        for subset in spec["table_2_subsets"]:
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


def claims(metrics: dict[str, pd.DataFrame], speeds: dict[str, str], spec: dict) -> list[dict]:
    """Paper C's claims decided on per-run RMSE (experiments.claims): metrics[label] is a
    scenario's per-run metrics.csv, speeds[label] its speed ("20 cm/s").

    Models and beacon sets of one scenario share their runs (paired); speeds are different
    scenarios (independent runs, Welch interval).
    """
    def rmse(label, subset, model, metric="rmse"):
        return claims_of.runs_of(metrics[label], metric, subset=subset, model=model)

    order = [claims_of.paired(rmse(label, spec["table_1_subset"], lo), rmse(label, spec["table_1_subset"], hi), "<",
                              f"{speeds[label]}: {lo} - {hi}")
             for label in metrics for lo, hi in zip(MODELS, MODELS[1:])]
    by_speed = sorted(metrics, key=lambda label: float(speeds[label].split()[0]))
    # speed on moving epochs only (metrics.tracking: rmse_moving): rests would mix the static share in
    speed = [claims_of.unpaired(rmse(slow, spec["table_1_subset"], m, "rmse_moving"),
                                rmse(fast, spec["table_1_subset"], m, "rmse_moving"), "<",
                                f"{m}: {speeds[slow]} - {speeds[fast]}, moving epochs (independent runs)")
             for m in MODELS for slow, fast in zip(by_speed, by_speed[1:])]
    beacons = []
    if spec["table_2_scenario"] in metrics:
        subsets = spec["table_2_subsets"]
        beacons = [claims_of.paired(rmse(spec["table_2_scenario"], more, m), rmse(spec["table_2_scenario"], fewer, m),
                                    "<", f"{m}: beacons {more} - {fewer}")
                   for m in MODELS for fewer, more in zip(subsets, subsets[1:])]
    return [claims_of.record("P < PV < PVA (Table I, every speed)", verdicts.claim(order)),
            claims_of.record("The error grows with speed (every model)", verdicts.claim(speed),
                             note="RMSE over the epochs at which the cart moves: "),
            claims_of.record("More beacons give a lower RMSE (Table II, every model)", verdicts.claim(beacons))]


def setup_rows(estimates: dict[str, pd.DataFrame], spec: dict) -> list[dict]:
    """Set-up facts per scenario (analysis.setup_facts) on the P model with Table I's
    beacons: the static share of epochs and the beacons ranged per epoch."""
    rows = []
    for label, est in estimates.items():
        cell = _table_1(est, spec, "P")
        rows += [setup_facts.fact_row(EXPERIMENT, "static share of epochs", label, setup_facts.static_share(cell),
                                      "share"),
                 setup_facts.fact_row(EXPERIMENT, "beacons ranged per epoch", label,
                                      setup_facts.measurements_per_epoch(cell), "count")]
    return rows


def noise_curves(grid: pd.DataFrame, spec: dict) -> dict[str, pd.DataFrame]:
    """Table I RMSE (m) of each model against the factor applied to its own a-priori sigma
    (a sensitivity sigma `model.parameter`), from one scenario's sensitivity grid
    (experiments.sensitivity): per model a frame x (factor), value (mean over the sampled
    runs), ci95_low, ci95_high."""
    cell = grid[grid["subset"] == spec["table_1_subset"]]
    curves = {}
    for model in MODELS:
        for sigma in (s for s in (spec.get("sensitivity") or {}).get("sigmas", []) if s.startswith(f"{model}.")):
            own = cell[(cell["model"] == model) & ((cell["setting"] == BASELINE) | (cell["sigma"] == sigma))]
            points = [(factor, *mean_interval(group["rmse"], "nonnegative"))
                      for factor, group in own.groupby("factor", sort=True)]
            if len(points) > 1:
                curves[f"{model} ({sigma.split('.', 1)[1]})"] = pd.DataFrame(points, columns=["x", "value", "ci95_low",
                                                                                            "ci95_high"])
    return curves


def anchor_curves(res: pd.DataFrame, spec: dict) -> dict:
    """Table II RMSE against the number of beacons, one line per model."""
    sel = res[(res["experiment"] == EXPERIMENT) & (res["table"] == "Table II") & (res["metric"] == "rmse_m")]
    curves = {}
    for model in MODELS:
        points = sorted((int(r.row.split(":")[0]), r.value) for r in sel[sel["column"] == model].itertuples())
        if points:
            curves[model] = ([p[0] for p in points], [p[1] for p in points])
    return curves


def subsets_of(spec: dict, label: str) -> list[str]:
    """Beacon subsets run on one scenario: Table I's, plus Table II's on its scenario."""
    subsets = spec["table_2_subsets"] if label == spec["table_2_scenario"] else []
    return list(dict.fromkeys(list(subsets) + [spec["table_1_subset"]]))


def _table_1(est: pd.DataFrame, spec: dict, model: str) -> pd.DataFrame:
    return est[(est["model"] == model) & (est["subset"] == spec["table_1_subset"])]


def cdf_panels(estimates: dict[str, pd.DataFrame], spec: dict) -> dict:
    """Error samples (all runs) per scenario and model, Table I's beacons."""
    return {label: {m: _table_1(est, spec, m)["error_m"].to_numpy() for m in MODELS}
            for label, est in estimates.items()}


def histogram_panels(estimates: dict[str, pd.DataFrame], spec: dict) -> dict:
    """Errors of each model on Table II's scenario (the paper's Fig. 4b)."""
    est = estimates.get(spec["table_2_scenario"])
    if est is None:
        return {}
    return {f"{m} ({spec['table_2_scenario']})": _table_1(est, spec, m)["error_m"] for m in MODELS}


def trajectory_panels(estimates: dict[str, pd.DataFrame], spec: dict) -> dict:
    """First run of Table II's scenario: truth and the three models' tracks."""
    est = estimates.get(spec["table_2_scenario"])
    if est is None:
        return {}
    first = est[est["run"] == est["run"].iloc[0]]
    truth = _table_1(first, spec, "P")[["true_x", "true_y"]].rename(columns={"true_x": "x", "true_y": "y"})
    return {f"{spec['table_2_scenario']}, {first['run'].iloc[0]}": (truth, {m: _table_1(first, spec, m)
                                                                          for m in MODELS})}
