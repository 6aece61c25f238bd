"""Paper D (Kianoush et al. 2012): Min-Max / multilateration on narrowband (RSS), UWB,
P-mix and F-mix ranges; velocity-bounded tracking; a Kalman filter for comparison.

Every cell is a registry estimator: the solvers `minmax` / `multilateration` on ranges
(UWB) or RSS distances (narrowband), the fusions `pmix` / `fmix`, and the trackers
`velocity_tracker` / `kf_tracker` over those fixes. This module holds only the paper's
table layout, its claims, the cost comparison and figures.
"""

from __future__ import annotations

import copy
import time

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.analysis import setup_facts
from wsnloc.campaign import Campaign
from wsnloc.experiments import calibration
from wsnloc.estimators import batched, trackers
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import cells, claims as claims_of
from wsnloc.estimators.trackers import fix_measurement, fix_motion
from wsnloc.filters.kalman import KalmanFilter
from wsnloc.metrics import op_counts, verdicts
from wsnloc.metrics.ranging import truth_at
from wsnloc.metrics.tracking import cell_metrics, score, true_speeds
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker

PAPER = "paper_d"
EXPERIMENT = "D"
INPUT_TABLES = ("ranges", "rss", "truth", "anchors")   # the processed tables a run needs (see load_runs)
TECHNIQUES = ("narrowband", "uwb", "pmix", "fmix")
LOCALIZER_LABEL = {"minmax": "Min-Max", "multilateration": "Multilateration"}
TECHNIQUE_LABEL = {"narrowband": "narrowband", "uwb": "UWB", "pmix": "P-mix", "fmix": "F-mix"}
TECHNIQUE_OF = {"narrowband": "rss", "uwb": "toa", "pmix": "pmix", "fmix": "fmix"}   # paper label -> registry
# The trackers of Tables 2 and 3: the paper's cells (config experiments.paper_d.estimators), each over
# every localizer's fixes; the raw stage (Table 1) is the localizer itself.
TRACKERS = cells.CELLS[PAPER]   # velocity, kalman
STAGES = ("raw",) + TRACKERS
COST_LABEL = {"velocity": "velocity tracker", "kalman": "Kalman filter"}


def cell_list(spec: dict, label: str, stages=STAGES) -> list[tuple[str, str, str, str, dict]]:
    """(localizer, technique, stage, registry estimator, its parameters on scenario `label`) of
    every cell of Tables 1-3 in the given stages: the raw fix is `minmax` / `multilateration` on
    RSS distances or ranges, or the fusion `pmix` / `fmix` with that solver; a tracker stage is
    its cell over those fixes."""
    out = []
    for localizer in LOCALIZER_LABEL:
        for technique, registry_technique in TECHNIQUE_OF.items():
            for stage in stages:
                if stage != "raw":
                    name, layout = cells.estimator(spec, stage), {"solver": localizer, "fixes": registry_technique}
                    out.append((localizer, technique, stage, name, cells.params(spec, stage, label, PAPER, layout)))
                    continue
                if technique in ("pmix", "fmix"):
                    name, layout = technique, {"solver": localizer}
                else:
                    name, layout = localizer, {"measurements": registry_technique}
                out.append((localizer, technique, stage, name, cells.layout_params(spec, name, label, PAPER, layout)))
    return out


def run_all(datas: list[RunData], spec: dict, label: str, stages=STAGES) -> list[pd.DataFrame]:
    """All estimates of each run (every cell of the given stages) of scenario `label`, scored
    against its truth; the cells of one registry estimator over all runs go through one
    batched.cell_tracks (the KF cells of every run and technique are stepped together)."""
    selected = cell_list(spec, label, stages)
    tracks: dict[int, list] = {}
    for name in dict.fromkeys(cell[3] for cell in selected):
        mine = [i for i, cell in enumerate(selected) if cell[3] == name]
        out = batched.cell_tracks(name, [(data, selected[i][4]) for i in mine for data in datas],
                                  where=cells.where(PAPER))
        for j, i in enumerate(mine):
            tracks[i] = out[j * len(datas):(j + 1) * len(datas)]
    return [score(batched.stacked([tracks[i][r] for i in range(len(selected))],
                                 {key: [cell[k] for cell in selected]
                                  for k, key in enumerate(("localizer", "technique", "stage"))},
                                 ("t", "x", "y")), data.table("truth"))
            for r, data in enumerate(datas)]


def run(data: RunData, spec: dict, label: str, stages=STAGES) -> pd.DataFrame:
    """run_all of one run."""
    return run_all([data], spec, label, stages)[0]


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per (localizer, technique, stage): the standard run metrics (metrics.tracking)."""
    return cell_metrics(estimates, ["localizer", "technique", "stage"], truth)


SPEEDLESS_ROW = "Kalman filter without speed input"      # Table 3's counterfactual row (speed_input_metrics)
SPEED_INPUT_METRICS = ("speed_input_share", "true_speed_mps", "speed_input_mps", "speed_bias_mps", "speed_rmse_mps",
                       "rmse_without_speed_m")
CELL_KEY = ["localizer", "technique", "stage"]


def speed_input_metrics(datas: list[RunData], spec: dict, label: str) -> list[pd.DataFrame]:
    """Per run, for every KF cell (stage "kalman") fed the velocity algorithm's speed
    (`speed_input`, seed 004 4.2): the speed it is fed (trackers.fix_source, the KF's own input)
    against the truth at the same fixes, and the same KF without it (a counterfactual). Columns:
    CELL_KEY and SPEED_INPUT_METRICS: the share of the KF's fixes that carry a speed estimate
    inside the truth span (v_hat needs two fixes; 0: the speed metrics are NaN), mean true speed
    ||p(t_k) - p(t_k-1)|| / (t_k - t_k-1) at the fixes that have a speed estimate
    (metrics.tracking.true_speeds, m/s), mean v_hat (eq. 1, m/s), mean and RMS of v_hat - v (m/s),
    and the RMSE (m) of the KF with speed_input false. Without a fed KF cell, frames of CELL_KEY
    only (merging them adds nothing)."""
    kalman = [cell for cell in cell_list(spec, label, ("kalman",)) if cell[4]["speed_input"]]
    if not kalman:
        return [pd.DataFrame(columns=CELL_KEY) for _ in datas]
    variant = copy.deepcopy(spec)
    variant["estimators"]["kalman"]["speed_input"] = False
    without = [run_metrics(est, data.table("truth")) for data, est in zip(datas, run_all(datas, variant, label,
                                                                                          ("kalman",)))]
    out = []
    for data, plain in zip(datas, without):
        truth, rows = data.table("truth"), []
        for localizer, technique, stage, _, p in kalman:
            source = trackers.fix_source(data, p)
            fixed = source.has_fix()
            t, v_hat = source.t[fixed], source.speed[fixed]
            v = true_speeds(t, *truth_at(truth, t).T)
            fed = np.isfinite(v_hat) & np.isfinite(v)
            v, v_hat = v[fed], v_hat[fed]
            cell = plain[(plain["localizer"] == localizer) & (plain["technique"] == technique)]
            rows.append({"localizer": localizer, "technique": technique, "stage": stage,
                         "speed_input_share": _mean_or_nan(fed), "true_speed_mps": _mean_or_nan(v),
                         "speed_input_mps": _mean_or_nan(v_hat), "speed_bias_mps": _mean_or_nan(v_hat - v),
                         "speed_rmse_mps": float(np.sqrt(_mean_or_nan((v_hat - v) ** 2))),
                         "rmse_without_speed_m": float(cell["rmse"].iloc[0]) if len(cell) else np.nan})
        out.append(pd.DataFrame(rows))
    return out


def _mean_or_nan(values: np.ndarray) -> float:
    return float(values.mean()) if len(values) else float("nan")


def speed_fed(spec: dict, label: str) -> dict[tuple[str, str], bool]:
    """Per (localizer, technique): whether its KF cell on scenario `label` is fed the speed."""
    return {(loc, tech): bool(p["speed_input"]) for loc, tech, _, _, p in cell_list(spec, label, ("kalman",))}


def rss_models_for_runs(run_tables: dict[str, dict], campaign: Campaign, spec: dict, label: str) -> dict[str, dict]:
    """RSS model per run (see wsnloc.experiments.calibration), fitted on the ZigBee anchors of
    the cells' `anchors` (the F-mix cell's parameters: every cell shares them)."""
    p = cells.layout_params(spec, "fmix", label, PAPER, {})
    zigbee = set(campaign.anchors_of("zigbee")["anchor_id"])
    members = [a for subset in p["anchors"].split("+") for a in campaign.spec["subsets"][subset] if a in zigbee]
    return calibration.rss_models_for_runs(run_tables, campaign, members, p)


def evaluate_runs(run_tables: dict[str, dict], campaign: Campaign, spec: dict, label: str) -> pd.DataFrame:
    """Per-run metrics of every cell on runs given as tables (e.g. extra simulated runs of
    scenario `label`), each run's RSS model calibrated as in the workflow (rss_models_for_runs)."""
    models = rss_models_for_runs(run_tables, campaign, spec, label)
    estimates = run_all([RunData(tables, campaign, models[name], name) for name, tables in run_tables.items()],
                        spec, label)
    return pd.concat([run_metrics(est, tables["truth"]).assign(run=name)
                      for (name, tables), est in zip(run_tables.items(), estimates)], ignore_index=True)


# ---- tables, claims and cost -------------------------------------------------------------

TABLES = {
    "Table 1": ("raw", "localization RMSE [m]"),
    "Table 2": ("velocity", "localization + velocity tracking RMSE [m]"),
}


def results_rows(metrics: pd.DataFrame, scenario: str, spec: dict) -> list[dict]:
    """results.csv rows: Tables 1-3 (RMSE) and their detail metrics, mean over runs with 95% CI;
    for each KF cell fed the speed (speed_fed, from the config) its SPEED_INPUT_METRICS, NaN over
    runs without a speed estimate (speed_input_share tells how many fixes had one). ValueError
    when a fed cell's metrics lack them (speed_input_metrics not merged)."""
    fed_cells = speed_fed(spec, scenario)
    rows = []
    common = {"experiment": EXPERIMENT, "scenario": scenario}
    for table, (stage, _) in TABLES.items():
        for localizer, loc_label in LOCALIZER_LABEL.items():
            for technique, tech_label in TECHNIQUE_LABEL.items():
                sel = metrics[(metrics["localizer"] == localizer) & (metrics["technique"] == technique)
                              & (metrics["stage"] == stage)]
                for metric in ("rmse", "median", "p95", "max", "availability"):
                    rows.append(results.row_over_runs(sel[metric], table=table, row=loc_label, column=tech_label,
                                                      metric=metric if metric == "availability" else f"{metric}_m",
                                                      **common))
    for stage, row in (("velocity", "velocity tracker"), ("kalman", "Kalman filter")):
        for technique, tech_label in TECHNIQUE_LABEL.items():
            sel = metrics[(metrics["localizer"] == "minmax") & (metrics["technique"] == technique)
                          & (metrics["stage"] == stage)]
            for metric in ("rmse", "median", "p95", "max"):
                rows.append(results.row_over_runs(sel[metric], table="Table 3", row=row, column=tech_label,
                                                  metric=f"{metric}_m", **common))
            if stage == "kalman" and fed_cells[("minmax", technique)]:
                missing = [metric for metric in SPEED_INPUT_METRICS if metric not in sel]
                if missing:
                    raise ValueError(f"paper D {scenario}: the Kalman filter on Min-Max {tech_label} fixes is fed the "
                                     f"speed (speed_input) but its per-run metrics lack {', '.join(missing)} "
                                     "(speed_input_metrics not merged)")
                rows += [results.row_over_runs(sel[metric], table="Table 3", row=row, column=tech_label,
                                               metric=metric, **common) for metric in SPEED_INPUT_METRICS[:-1]]
                rows.append(results.row_over_runs(sel["rmse_without_speed_m"], table="Table 3",
                                                  row=SPEEDLESS_ROW, column=tech_label, metric="rmse_m", **common))
    return rows


def measure_cost(spec: dict, label: str, repeats: int = 5) -> dict[str, float]:
    """Median time per step (microseconds) of the velocity tracker and the KF on this machine,
    with their cells' parameters on scenario `label`.

    Each repeat feeds `cost_iterations` noisy fixes of a straight walk; the median over
    repeats of the mean time per step is reported.
    """
    rng = np.random.default_rng(0)
    velocity, kalman = (cells.params(spec, cell, label, PAPER) for cell in TRACKERS)
    n = spec["cost_iterations"]
    t = np.arange(n) * kalman["epoch_s"]
    fixes = np.column_stack([0.3 * t, np.zeros(n)]) + rng.normal(0, 1.0, (n, 2))
    motion = fix_motion(kalman["epoch_s"], kalman["accel_sigma_mps2"], kalman["position_sigma_m"],
                        kalman["initial_speed_sigma_mps"])
    F, Q, _ = motion.matrices(kalman["epoch_s"])
    H, R = fix_measurement(kalman["position_sigma_m"])
    P0 = motion.initial_covariance()
    per_step = {"velocity": [], "kalman": []}
    for _ in range(repeats):
        tracker = VelocityBoundedTracker(velocity["window"], velocity["speed_from"])
        start = time.perf_counter()
        for k in range(n):
            tracker.step(t[k], fixes[k])
        per_step["velocity"].append((time.perf_counter() - start) / n * 1e6)
        kf = KalmanFilter(np.array([*fixes[0], 0, 0]), P0, F, Q, H, R)
        start = time.perf_counter()
        for k in range(n):
            kf.predict()
            kf.update(fixes[k])
        per_step["kalman"].append((time.perf_counter() - start) / n * 1e6)
    return {name: float(np.median(v)) for name, v in per_step.items()}


def cost_rows(cost_us: dict[str, float], paper_ms: dict[str, float]) -> list[dict]:
    """Measured time per step (us) beside the paper's (ms on a 200 MHz SA-110, given in us)."""
    rows = [results.single_row(cost_us[name], experiment=EXPERIMENT, table="Cost", row=label,
                               column="time per step", scenario="this machine", metric="us_per_step",
                               paper_value=paper_ms[label] * 1000.0)
            for name, label in COST_LABEL.items()]
    rows.append(results.single_row(cost_us["kalman"] / cost_us["velocity"], experiment=EXPERIMENT, table="Cost",
                                   row="Kalman / velocity", column="time per step", scenario="this machine",
                                   metric="ratio", paper_value=paper_ms["Kalman filter"] / paper_ms["velocity tracker"]))
    return rows


def operation_counts(spec: dict, label: str) -> dict[str, dict]:
    """Arithmetic operations per step of both trackers and their ratios (metrics.op_counts),
    with the velocity cell's window on scenario `label`."""
    return op_counts.cost_table(cells.params(spec, "velocity", label, PAPER)["window"])


def operation_rows(counts: dict[str, dict], paper_ms: dict[str, float]) -> list[dict]:
    """results.csv rows of the operation counts per step (machine-independent, reproducible):
    per tracker the total and each operation kind; the Kalman / velocity ratio of totals
    beside the paper's ratio of times (72 ms / 12 ms on a 200 MHz SA-110)."""
    common = {"experiment": EXPERIMENT, "table": "Cost", "scenario": "operation count", "metric": "ops_per_step"}
    rows = [results.single_row(counts[label][kind], row=label, column=f"{kind} per step", **common)
            for label in COST_LABEL.values() for kind in (*op_counts.OPERATIONS, "total")]
    rows.append(results.single_row(counts["Kalman / velocity"]["total"], **{**common, "metric": "ratio"},
                                   row="Kalman / velocity", column="total per step",
                                   paper_value=paper_ms["Kalman filter"] / paper_ms["velocity tracker"]))
    return rows


def claims(metrics: dict[str, pd.DataFrame]) -> list[dict]:
    """Each published claim of paper D decided on per-run RMSE (experiments.claims), paired
    within each scenario (metrics[label] is its per-run metrics.csv). Where a claim names
    "the best" cell, the best is chosen by the mean over runs, then compared run by run.
    """
    fusion, fmix_best, tracking, fmix_tracked, minmax, kalman = [], [], [], [], [], []
    for label, per_run in metrics.items():
        def rmse(localizer, technique, stage="raw"):
            return claims_of.runs_of(per_run, localizer=localizer, technique=technique, stage=stage)

        def best(localizers, techniques, stage="raw"):
            return min(((loc, t) for loc in localizers for t in techniques),
                       key=lambda cell: rmse(*cell, stage).mean())

        def compare(a, b):
            return claims_of.paired(rmse(*a), rmse(*b), "<", f"{label}: {_cell_name(*a)} - {_cell_name(*b)}")

        for loc in LOCALIZER_LABEL:
            fusion.append(compare(best([loc], ("pmix", "fmix")), best([loc], ("narrowband", "uwb"))))
            fmix_best += [compare((loc, "fmix"), (loc, t)) for t in TECHNIQUES if t != "fmix"]
            tracking += [compare((loc, t, "velocity"), (loc, t)) for t in TECHNIQUES]
        winner = best(LOCALIZER_LABEL, ["fmix"], "velocity")
        fmix_tracked += [compare((*winner, "velocity"), (loc, t, "velocity"))
                         for loc in LOCALIZER_LABEL for t in TECHNIQUES if t != "fmix"]
        minmax += [compare(("minmax", t), ("multilateration", t)) for t in TECHNIQUES]
        kf, velocity = rmse("minmax", "fmix", "kalman"), rmse("minmax", "fmix", "velocity")
        kalman += [compare(("minmax", "fmix", "kalman"), ("minmax", "fmix", "velocity")),
                   claims_of.paired(velocity, 1.25 * kf, "<", f"{label}: Min-Max F-mix + velocity - 1.25 x KF")]
    return [claims_of.record("Fusion beats a single source", verdicts.claim(fusion)),
            claims_of.record("F-mix is the best fusion and technique", verdicts.claim(fmix_best)),
            claims_of.record("Velocity tracking lowers the RMSE in every cell", verdicts.claim(tracking)),
            claims_of.record("F-mix followed by velocity tracking gives the lowest RMSE", verdicts.claim(fmix_tracked)),
            claims_of.record("Min-Max is more accurate than multilateration", verdicts.claim(minmax)),
            claims_of.record("The Kalman filter is slightly more accurate than the velocity tracker (within 25%)",
                             verdicts.claim(kalman))]


def _cell_name(localizer: str, technique: str, stage: str = "raw") -> str:
    suffix = {"raw": "", "velocity": " + velocity", "kalman": " + KF"}[stage]
    return f"{LOCALIZER_LABEL[localizer]} {TECHNIQUE_LABEL[technique]}{suffix}"


def cost_claim(counts: dict[str, dict], paper_ms: dict[str, float]) -> dict:
    """Paper D: the KF costs about 6x the velocity tracker per step (72 ms vs 12 ms on a
    200 MHz SA-110), decided on the machine-independent operation counts: the claim holds
    when the KF needs more than twice the tracker's arithmetic operations per step."""
    ratio = counts["Kalman / velocity"]["total"]
    paper = paper_ms["Kalman filter"] / paper_ms["velocity tracker"]

    def ops(c):
        return f"{c['total']} ({c['mul']} mul, {c['add']} add, {c['div']} div, {c['sqrt']} sqrt)"

    return claims_of.decided_record(
        "The Kalman filter is several times costlier per step than the velocity tracker", ratio > 2.0,
        f"operations per step: KF {ops(counts['Kalman filter'])}, velocity tracker {ops(counts['velocity tracker'])}: "
        f"ratio {ratio:.1f} (> 2 claimed; the paper's ratio of times is {paper:.0f})")


def setup_rows(estimates: dict[str, pd.DataFrame]) -> list[dict]:
    """Set-up facts per scenario (analysis.setup_facts): the static share of the epochs."""
    return [setup_facts.fact_row(EXPERIMENT, "static share of epochs", label,
                                 setup_facts.static_share(_select(est, "minmax", "uwb", "raw")), "share")
            for label, est in estimates.items()]


FIGURE_CURVES = {   # label: (localizer, technique, stage)
    "Min-Max narrowband": ("minmax", "narrowband", "raw"),
    "Min-Max UWB": ("minmax", "uwb", "raw"),
    "Min-Max F-mix": ("minmax", "fmix", "raw"),
    "Min-Max F-mix + velocity": ("minmax", "fmix", "velocity"),
    "Min-Max F-mix + KF": ("minmax", "fmix", "kalman"),
    "Multilateration F-mix": ("multilateration", "fmix", "raw"),
}


def _select(est: pd.DataFrame, localizer: str, technique: str, stage: str) -> pd.DataFrame:
    return est[(est["localizer"] == localizer) & (est["technique"] == technique) & (est["stage"] == stage)]


def cdf_panels(estimates: dict[str, pd.DataFrame]) -> dict:
    """Error samples (all runs) per scenario and curve, for the CDF figure."""
    return {label: {name: _select(est, *key)["error_m"].to_numpy() for name, key in FIGURE_CURVES.items()}
            for label, est in estimates.items()}


def trajectory_panels(estimates: dict[str, pd.DataFrame]) -> dict:
    """First run of each scenario: truth and the Min-Max F-mix tracks."""
    panels = {}
    for label, est in estimates.items():
        first = est[est["run"] == est["run"].iloc[0]]
        raw = _select(first, "minmax", "fmix", "raw")
        truth = raw[["true_x", "true_y"]].rename(columns={"true_x": "x", "true_y": "y"})
        tracks = {name: _select(first, *key) for name, key in FIGURE_CURVES.items() if key[0] == "minmax" and key[1] == "fmix"}
        panels[f"{label}, {first['run'].iloc[0]}: Min-Max F-mix"] = (truth, tracks)
    return panels
