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
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError
from wsnloc.experiments import calibration
from wsnloc.estimators import registry
from wsnloc.estimators.run_data import RunData
from wsnloc.estimators.trackers import kalman_matrices
from wsnloc.filters.kalman import KalmanFilter
from wsnloc.metrics.tracking import cell_metrics, score
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker

EXPERIMENT = "D"
INPUT_TABLES = ("ranges", "rss", "truth", "anchors")   # the processed tables a run needs (see load_runs)
TECHNIQUES = ("narrowband", "uwb", "pmix", "fmix")
LOCALIZER_LABEL = {"minmax": "Min-Max", "multilateration": "Multilateration"}
TECHNIQUE_LABEL = {"narrowband": "narrowband", "uwb": "UWB", "pmix": "P-mix", "fmix": "F-mix"}
COST_LABEL = {"velocity": "velocity tracker", "kalman": "Kalman filter"}


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

    @classmethod
    def from_config(cls, spec: dict) -> "Settings":
        return cls(epoch_s=spec["epoch_s"], k_smallest=spec["k_smallest"], uwb_subset=spec["subsets"]["uwb"],
                   narrowband_subset=spec["subsets"]["narrowband"],
                   uwb_preliminary_filter=spec["uwb_preliminary_filter"], max_range_m=spec["max_range_m"],
                   rss_calibration=spec["rss_calibration"], rss_model=spec["rss_model"],
                   pmix_weights=spec["pmix_weights"], tracker_window=spec["tracker"]["window"],
                   tracker_speed_from=spec["tracker"]["speed_from"], kalman=spec["kalman"],
                   cost_iterations=spec["cost_iterations"])


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
            "initial_speed_sigma_mps": k["initial_speed_sigma_mps"]}


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


def run(data: RunData, settings: Settings) -> pd.DataFrame:
    """All estimates of one run (every cell), scored against its truth."""
    frames = [registry.run(name, data, params, where="experiments.paper_d")[["t", "x", "y"]]
              .assign(localizer=loc, technique=tech, stage=stage)
              for loc, tech, stage, name, params in cells(settings)]
    return score(pd.concat(frames, ignore_index=True), data.table("truth"))


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per (localizer, technique, stage): the standard run metrics (metrics.tracking)."""
    return cell_metrics(estimates, ["localizer", "technique", "stage"], truth)


def rss_models_for_runs(run_tables: dict[str, dict], campaign: Campaign, settings: Settings) -> dict[str, dict]:
    """RSS model per run (see wsnloc.experiments.calibration)."""
    members = campaign.spec["subsets"][settings.narrowband_subset]
    return calibration.rss_models_for_runs(run_tables, campaign, members, settings.rss_calibration, settings.rss_model)


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


def _rmse(res: pd.DataFrame, table: str, row: str, column: str, scenario: str) -> float:
    sel = res[(res["experiment"] == EXPERIMENT) & (res["table"] == table) & (res["row"] == row)
              & (res["column"] == column) & (res["scenario"] == scenario) & (res["metric"] == "rmse_m")]
    return float(sel["value"].iloc[0]) if len(sel) else float("nan")


def claims(res: pd.DataFrame, scenarios: list[str]) -> list[dict]:
    """Each published claim of paper D, checked on our results, with the deciding numbers."""
    out = []
    locs = list(LOCALIZER_LABEL.values())
    techs = list(TECHNIQUE_LABEL.values())

    def check(text, cases):
        holds = all(ok for ok, _ in cases)
        out.append({"claim": text, "holds": holds, "evidence": "; ".join(e for _, e in cases)})

    cases = []
    for sc in scenarios:
        for loc in locs:
            single = min(_rmse(res, "Table 1", loc, t, sc) for t in ("narrowband", "UWB"))
            fused = min(_rmse(res, "Table 1", loc, t, sc) for t in ("P-mix", "F-mix"))
            cases.append((fused < single, f"{sc} {loc}: best fusion {fused:.3f} vs best single {single:.3f} m"))
    check("Fusion beats a single source", cases)

    cases = []
    for sc in scenarios:
        for loc in locs:
            values = {t: _rmse(res, "Table 1", loc, t, sc) for t in techs}
            best = min(values, key=values.get)
            cases.append((best == "F-mix", f"{sc} {loc}: best is {best} ({values[best]:.3f} m; F-mix {values['F-mix']:.3f} m)"))
    check("F-mix is the best fusion and technique", cases)

    cases = []
    for sc in scenarios:
        for loc in locs:
            for t in techs:
                before, after = _rmse(res, "Table 1", loc, t, sc), _rmse(res, "Table 2", loc, t, sc)
                cases.append((after < before, f"{sc} {loc} {t}: {before:.3f} -> {after:.3f} m"))
    check("Velocity tracking lowers the RMSE in every cell", cases)

    cases = []
    for sc in scenarios:
        table2 = {(loc, t): _rmse(res, "Table 2", loc, t, sc) for loc in locs for t in techs}
        best = min(table2, key=table2.get)
        cases.append((best[1] == "F-mix", f"{sc}: lowest with tracking is {best[0]} {best[1]} ({table2[best]:.3f} m)"))
    check("F-mix followed by velocity tracking gives the lowest RMSE", cases)

    cases = []
    for sc in scenarios:
        for t in techs:
            mm, ml = _rmse(res, "Table 1", "Min-Max", t, sc), _rmse(res, "Table 1", "Multilateration", t, sc)
            cases.append((mm < ml, f"{sc} {t}: Min-Max {mm:.3f} vs multilateration {ml:.3f} m"))
    check("Min-Max is more accurate than multilateration", cases)

    cases = []
    for sc in scenarios:
        kf, vel = _rmse(res, "Table 3", "Kalman filter", "F-mix", sc), _rmse(res, "Table 3", "velocity tracker", "F-mix", sc)
        cases.append((kf < vel <= 1.25 * kf, f"{sc} Min-Max F-mix: KF {kf:.3f} vs velocity {vel:.3f} m"))
    check("The Kalman filter is slightly more accurate than the velocity tracker (within 25%)", cases)
    return out


def cost_claim(cost_us: dict[str, float], paper_ms: dict[str, float]) -> dict:
    """Paper D: the KF costs about 6x the velocity tracker per step (72 ms vs 12 ms)."""
    ratio = cost_us["kalman"] / cost_us["velocity"]
    paper = paper_ms["Kalman filter"] / paper_ms["velocity tracker"]
    return {"claim": "The Kalman filter is several times costlier per step than the velocity tracker",
            "holds": bool(ratio > 2.0),
            "evidence": f"this machine: KF {cost_us['kalman']:.1f} us, velocity {cost_us['velocity']:.1f} us per step "
                        f"(ratio {ratio:.1f}; paper {paper:.0f} on a 200 MHz SA-110)"}


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
