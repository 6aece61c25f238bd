"""Paper D (Kianoush et al. 2012): Min-Max / multilateration on narrowband (RSS), UWB,
P-mix and F-mix ranges; velocity-bounded tracking; a Kalman filter for comparison.

Every cell is a registry estimator: the solvers `minmax` / `multilateration` on ranges
(UWB) or RSS distances (narrowband), the fusions `pmix` / `fmix`, and the trackers
`velocity_tracker` / `kf_tracker` over those fixes. This module holds only the paper's
table layout, its claims, the cost comparison and figures.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.analysis import setup_facts
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError
from wsnloc.experiments import calibration
from wsnloc.estimators import batched, registry
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import claims as claims_of
from wsnloc.estimators.trackers import kalman_matrices
from wsnloc.filters.kalman import KalmanFilter
from wsnloc.metrics import op_counts, verdicts
from wsnloc.metrics.tracking import cell_metrics, score
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker

EXPERIMENT = "D"
INPUT_TABLES = ("ranges", "rss", "truth", "anchors")   # the processed tables a run needs (see load_runs)
TECHNIQUES = ("narrowband", "uwb", "pmix", "fmix")
LOCALIZER_LABEL = {"minmax": "Min-Max", "multilateration": "Multilateration"}
TECHNIQUE_LABEL = {"narrowband": "narrowband", "uwb": "UWB", "pmix": "P-mix", "fmix": "F-mix"}
COST_LABEL = {"velocity": "velocity tracker", "kalman": "Kalman filter"}
# The a-priori sigmas of paper D: the comparison KF's (they act on its cells only).
SENSITIVITY_SIGMAS = ("kalman.accel_sigma_mps2", "kalman.position_sigma_m", "kalman.initial_speed_sigma_mps")


@dataclass
class Settings:
    """Paper D parameters from config (experiments.paper_d)."""

    epoch_s: float
    k_smallest: int
    uwb_subset: str
    narrowband_subset: str
    uwb_preliminary_filter: bool
    max_range_m: float
    rss_calibration: str
    rss_model: dict
    pmix_weights: dict
    tracker_window: int
    tracker_speed_from: str
    kalman: dict
    cost_iterations: int
    multilateration_refine: bool = False

    @classmethod
    def from_config(cls, spec: dict) -> "Settings":
        return cls(epoch_s=spec["epoch_s"], k_smallest=spec["k_smallest"], uwb_subset=spec["subsets"]["uwb"],
                   narrowband_subset=spec["subsets"]["narrowband"],
                   uwb_preliminary_filter=spec["uwb_preliminary_filter"], max_range_m=spec["max_range_m"],
                   rss_calibration=spec["rss_calibration"], rss_model=spec["rss_model"],
                   pmix_weights=spec["pmix_weights"], tracker_window=spec["tracker"]["window"],
                   tracker_speed_from=spec["tracker"]["speed_from"], kalman=spec["kalman"],
                   cost_iterations=spec["cost_iterations"], multilateration_refine=spec["multilateration_refine"])


    def check_against(self, campaign: Campaign) -> None:
        """Anchor subsets must exist in the campaign file; names the config key otherwise."""
        for role, name in (("uwb", self.uwb_subset), ("narrowband", self.narrowband_subset)):
            if name not in campaign.spec.get("subsets", {}):
                raise ConfigError(f"config key 'experiments.paper_d.subsets.{role}': no subset {name!r} "
                                  f"in {campaign.source} (has: {', '.join(campaign.spec.get('subsets', {}))})")


TECHNIQUE_OF = {"narrowband": "rss", "uwb": "toa", "pmix": "pmix", "fmix": "fmix"}   # paper label -> registry


def estimator_params(settings: Settings) -> dict:
    """Registry parameters shared by paper D's cells (fixes, fusions and both trackers)."""
    w = settings.pmix_weights
    k = settings.kalman
    return {"anchors": f"{settings.uwb_subset}+{settings.narrowband_subset}", "epoch_s": settings.epoch_s,
            "k_smallest": settings.k_smallest, "preliminary_filter": settings.uwb_preliminary_filter,
            "max_range_m": settings.max_range_m, "rss_calibration": settings.rss_calibration,
            "p0_dbm": settings.rss_model["p0_dbm"], "path_loss_exponent": settings.rss_model["path_loss_exponent"],
            "d0_m": settings.rss_model.get("d0_m", 1.0), "pmix_toa_weight": w["uwb"] / (w["uwb"] + w["narrowband"]),
            "window": settings.tracker_window, "speed_from": settings.tracker_speed_from,
            "accel_sigma_mps2": k["accel_sigma_mps2"], "position_sigma_m": k["position_sigma_m"],
            "initial_speed_sigma_mps": k["initial_speed_sigma_mps"], "speed_input": k["speed_input"],
            "speed_sigma_mps": k["speed_sigma_mps"], "refine": settings.multilateration_refine}


def cells(settings: Settings) -> list[tuple[str, str, str, str, dict]]:
    """(localizer, technique, stage, registry estimator, its parameters) of every cell of Tables 1-3."""
    base = estimator_params(settings)
    out = []
    for localizer in LOCALIZER_LABEL:
        for technique, registry_technique in TECHNIQUE_OF.items():
            if technique in ("pmix", "fmix"):
                raw = (technique, {"solver": localizer})
            else:
                raw = (localizer, {"measurements": registry_technique})
            tracked = {"solver": localizer, "fixes": registry_technique}
            out += [(localizer, technique, "raw", raw[0], raw[1]),
                    (localizer, technique, "velocity", "velocity_tracker", tracked),
                    (localizer, technique, "kalman", "kf_tracker", tracked)]
    return [(loc, tech, stage, name, {k: v for k, v in {**base, **extra}.items() if k in _names(name)})
            for loc, tech, stage, name, extra in out]


def _names(estimator: str) -> set[str]:
    return {p.name for p in registry.get(estimator).params}


def run_all(datas: list[RunData], settings: Settings, stages=("raw", "velocity", "kalman")) -> list[pd.DataFrame]:
    """All estimates of each run (every cell of the given stages), scored against its truth; the
    cells of one registry estimator over all runs go through one batched.cell_tracks (the KF
    cells of every run and technique are stepped together)."""
    selected = [cell for cell in cells(settings) if cell[2] in stages]
    tracks: dict[int, list[batched.Track]] = {}
    for name in dict.fromkeys(cell[3] for cell in selected):
        mine = [i for i, cell in enumerate(selected) if cell[3] == name]
        out = batched.cell_tracks(name, [(data, selected[i][4]) for i in mine for data in datas],
                                  where="experiments.paper_d")
        for j, i in enumerate(mine):
            tracks[i] = out[j * len(datas):(j + 1) * len(datas)]
    return [score(batched.stacked([tracks[i][r] for i in range(len(selected))],
                                 {key: [cell[k] for cell in selected]
                                  for k, key in enumerate(("localizer", "technique", "stage"))},
                                 ("t", "x", "y")), data.table("truth"))
            for r, data in enumerate(datas)]


def run(data: RunData, settings: Settings, stages=("raw", "velocity", "kalman")) -> pd.DataFrame:
    """run_all of one run."""
    return run_all([data], settings, stages)[0]


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per (localizer, technique, stage): the standard run metrics (metrics.tracking)."""
    return cell_metrics(estimates, ["localizer", "technique", "stage"], truth)


def rss_models_for_runs(run_tables: dict[str, dict], campaign: Campaign, settings: Settings) -> dict[str, dict]:
    """RSS model per run (see wsnloc.experiments.calibration)."""
    members = campaign.spec["subsets"][settings.narrowband_subset]
    return calibration.rss_models_for_runs(run_tables, campaign, members, settings.rss_calibration, settings.rss_model)


def evaluate_runs(run_tables: dict[str, dict], campaign: Campaign, settings: Settings) -> pd.DataFrame:
    """Per-run metrics of every cell on runs given as tables (e.g. extra simulated runs),
    each run's RSS model calibrated as in the workflow (rss_models_for_runs)."""
    models = rss_models_for_runs(run_tables, campaign, settings)
    estimates = run_all([RunData(tables, campaign, models[name], name) for name, tables in run_tables.items()], settings)
    return pd.concat([run_metrics(est, tables["truth"]).assign(run=name)
                      for (name, tables), est in zip(run_tables.items(), estimates)], ignore_index=True)


# ---- tables, claims and cost -------------------------------------------------------------

TABLES = {
    "Table 1": ("raw", "localization RMSE [m]"),
    "Table 2": ("velocity", "localization + velocity tracking RMSE [m]"),
}


def results_rows(metrics: pd.DataFrame, scenario: str) -> list[dict]:
    """results.csv rows: Tables 1-3 (RMSE) and their detail metrics, mean over runs with 95% CI."""
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
    return rows


def measure_cost(settings: Settings, repeats: int = 5) -> dict[str, float]:
    """Median time per step (microseconds) of the velocity tracker and the KF on this machine.

    Each repeat feeds `cost_iterations` noisy fixes of a straight walk; the median over
    repeats of the mean time per step is reported.
    """
    rng = np.random.default_rng(0)
    n = settings.cost_iterations
    t = np.arange(n) * settings.epoch_s
    fixes = np.column_stack([0.3 * t, np.zeros(n)]) + rng.normal(0, 1.0, (n, 2))
    k = settings.kalman
    F, Q, H, R, P0 = kalman_matrices(settings.epoch_s, k["accel_sigma_mps2"], k["position_sigma_m"],
                                     k["initial_speed_sigma_mps"])
    per_step = {"velocity": [], "kalman": []}
    for _ in range(repeats):
        tracker = VelocityBoundedTracker(settings.tracker_window, settings.tracker_speed_from)
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


def operation_counts(settings: Settings) -> dict[str, dict]:
    """Arithmetic operations per step of both trackers and their ratios (metrics.op_counts)."""
    return op_counts.cost_table(settings.tracker_window)


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
