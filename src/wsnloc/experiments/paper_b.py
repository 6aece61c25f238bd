"""Paper B (Pavia group, c. 2013): UWB Min-Max fixes fused with inertial dead reckoning
by a steady-state Kalman filter, beside the classical (time-varying gain) KF.

Per run: dead reckoning on the 5 Hz IMU from the known start pose; Min-Max fixes at every
UWB epoch (2 Hz); both filters predict with the dead-reckoning displacement of each
5 Hz step and update with the fix that arrived during the step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError
from wsnloc.experiments.epochs import build_epochs, score
from wsnloc.experiments.paper_d import preliminary_filter
from wsnloc.filters.steady_state import fuse, steady_state_gain
from wsnloc.geometry.lateration import min_max
from wsnloc.geometry.selection import k_smallest
from wsnloc.inertial.dead_reckoning import dead_reckon, static_bias
from wsnloc.io.tables import empty as empty_table
from wsnloc.metrics.stats import error_summary

EXPERIMENT = "B"
INPUT_TABLES = ("ranges", "truth")   # the processed tables a run needs (see load_runs)
METHODS = {"uwb": "UWB only (Min-Max)", "imu": "IMU only (dead reckoning)",
           "sskf": "steady-state KF fusion", "kf": "classical KF fusion"}


@dataclass
class Settings:
    epoch_s: float
    uwb_subset: str
    k_smallest: int
    uwb_preliminary_filter: bool
    max_range_m: float
    static_bias_s: float
    process_sigma_m: float
    fix_sigma_m: float

    @classmethod
    def from_config(cls, spec: dict) -> "Settings":
        keys = cls.__dataclass_fields__
        return cls(**{k: spec[k] for k in keys})

    def check_against(self, campaign: Campaign) -> None:
        if self.uwb_subset not in campaign.spec.get("subsets", {}):
            raise ConfigError(f"config key 'experiments.paper_b.uwb_subset': no subset {self.uwb_subset!r} "
                              f"in {campaign.source}")


def uwb_fixes(ranges: pd.DataFrame, campaign: Campaign, settings: Settings) -> pd.DataFrame:
    """Min-Max fix (x, y; NaN when none) at the end of every UWB epoch."""
    members = campaign.spec["subsets"][settings.uwb_subset]
    ranges = ranges[ranges["anchor_id"].isin(members)]
    ranges = preliminary_filter(ranges, settings.max_range_m) if settings.uwb_preliminary_filter \
        else ranges[np.isfinite(ranges["range_m"])]
    xy = {a: (x, y) for a, x, y in campaign.anchors[["anchor_id", "x", "y"]].itertuples(index=False)}
    rows = []
    for epoch in build_epochs(ranges, empty_table("rss"), settings.epoch_s):
        keep = k_smallest(epoch.ranges, settings.k_smallest or len(epoch.ranges))
        anchors = np.array([xy[a] for a in epoch.range_ids[keep]]).reshape(-1, 2)
        fix = min_max(anchors, epoch.ranges[keep])
        rows.append((epoch.t, *(fix if fix is not None else (np.nan, np.nan))))
    return pd.DataFrame(rows, columns=["t", "x", "y"])


def align_fixes(step_times: np.ndarray, fixes: pd.DataFrame) -> np.ndarray:
    """(N - 1, 2): the fix that arrived during step k (t_k, t_{k+1}], NaN where none."""
    out = np.full((len(step_times) - 1, 2), np.nan)
    valid = fixes.dropna()
    index = np.searchsorted(step_times, valid["t"].to_numpy(), side="left") - 1
    inside = (index >= 0) & (index < len(out))
    out[index[inside]] = valid[["x", "y"]].to_numpy()[inside]
    return out


def filter_matrices(settings: Settings, imu_step_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q per 5 Hz step, R of a fix, and the steady-state gain for one update per UWB epoch."""
    Q_step = np.eye(2) * settings.process_sigma_m**2
    R = np.eye(2) * settings.fix_sigma_m**2
    steps_per_update = settings.epoch_s / imu_step_s
    return Q_step, R, steady_state_gain(Q_step * steps_per_update, R)


def run(tables: dict, imu_5hz: pd.DataFrame, campaign: Campaign, settings: Settings) -> pd.DataFrame:
    """UWB-only, IMU-only, steady-state KF and classical KF positions of one run, scored."""
    x0, y0, heading0 = campaign.path.start_pose()
    imu = imu_5hz.reset_index(drop=True)
    dr = dead_reckon(imu, x0, y0, heading0, static_bias(imu, settings.static_bias_s))
    fixes = uwb_fixes(tables["ranges"], campaign, settings)
    t = dr["t"].to_numpy()
    step = float(np.median(np.diff(t)))
    Q_step, R, gain = filter_matrices(settings, step)
    displacements = np.diff(dr[["x", "y"]].to_numpy(), axis=0)
    aligned = align_fixes(t, fixes)
    start = (x0, y0)
    sskf = fuse(displacements, aligned, start, Q_step, R, gain=gain)
    kf = fuse(displacements, aligned, start, Q_step, R, P0=np.zeros((2, 2)))
    frames = [
        fixes.assign(method="uwb"),
        dr[["t", "x", "y"]].assign(method="imu"),
        pd.DataFrame({"t": t, "x": sskf[:, 0], "y": sskf[:, 1], "method": "sskf"}),
        pd.DataFrame({"t": t, "x": kf[:, 0], "y": kf[:, 1], "method": "kf"}),
    ]
    return score(pd.concat(frames, ignore_index=True), tables["truth"])


def run_metrics(estimates: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for method, group in estimates.groupby("method", sort=False):
        stats = error_summary(group["error_m"])
        rows.append({"method": method, **{k: stats[k] for k in ("rmse", "median", "p95", "max")}})
    return pd.DataFrame(rows)


def results_rows(metrics: pd.DataFrame, scenario: str, paper: dict, simulated_setup: bool) -> list[dict]:
    """RMSE and max error per method; the paper's simulation or real-data value beside ours."""
    published = {row["row"]: row for row in paper["rmse_m"]}
    rows = []
    for method, label in METHODS.items():
        sel = metrics[metrics["method"] == method]
        ref = published.get(label, {})
        rmse_paper = ref.get("simulation" if simulated_setup else "real")
        max_paper = None if simulated_setup else ref.get("max_real")
        rows.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table="RMSE", row=label,
                                          column=scenario, scenario=scenario, metric="rmse_m",
                                          paper_value=rmse_paper))
        rows.append(results.row_over_runs(sel["max"], experiment=EXPERIMENT, table="Max error", row=label,
                                          column=scenario, scenario=scenario, metric="max_m",
                                          paper_value=max_paper if isinstance(max_paper, (int, float)) else None))
        for metric in ("median", "p95"):
            rows.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table="Detail", row=label,
                                              column=metric, scenario=scenario, metric=f"{metric}_m"))
    return rows


def claims(res: pd.DataFrame, scenarios: list[str]) -> list[dict]:
    """Paper B's claims checked on our RMSE values."""
    def rmse(method, scenario):
        sel = res[(res["experiment"] == EXPERIMENT) & (res["table"] == "RMSE") & (res["row"] == METHODS[method])
                  & (res["scenario"] == scenario)]
        return float(sel["value"].iloc[0]) if len(sel) else float("nan")

    fusion, classical = [], []
    for sc in scenarios:
        ss, uwb, imu, kf = (rmse(m, sc) for m in ("sskf", "uwb", "imu", "kf"))
        fusion.append((ss < uwb and ss < imu, f"{sc}: steady-state {ss:.3f} vs UWB {uwb:.3f} and IMU {imu:.3f} m"))
        classical.append((kf < ss, f"{sc}: classical {kf:.3f} vs steady-state {ss:.3f} m"))
    return [
        {"claim": "Fusion beats both UWB only and IMU only", "holds": all(ok for ok, _ in fusion),
         "evidence": "; ".join(e for _, e in fusion)},
        {"claim": "The classical KF is somewhat better than the steady-state KF", "holds": all(ok for ok, _ in classical),
         "evidence": "; ".join(e for _, e in classical)},
    ]


FIGURE_METHODS = ("uwb", "imu", "sskf")


def _first_run(est: pd.DataFrame) -> pd.DataFrame:
    return est[est["run"] == est["run"].iloc[0]]


def trajectory_panels(estimates: dict[str, pd.DataFrame]) -> dict:
    """First run of each scenario: truth and the UWB-only, IMU-only and fused tracks."""
    panels = {}
    for label, est in estimates.items():
        first = _first_run(est)
        truth = first[first["method"] == "imu"][["true_x", "true_y"]].rename(columns={"true_x": "x", "true_y": "y"})
        tracks = {METHODS[m]: first[first["method"] == m] for m in FIGURE_METHODS}
        panels[f"{label}, {first['run'].iloc[0]}"] = (truth, tracks)
    return panels


def error_panels(estimates: dict[str, pd.DataFrame]) -> dict:
    """First run of each scenario: position error over time per method."""
    return {f"{label}, {_first_run(est)['run'].iloc[0]}":
            {METHODS[m]: _first_run(est)[_first_run(est)["method"] == m][["t", "error_m"]] for m in FIGURE_METHODS}
            for label, est in estimates.items()}


def cdf_panels(estimates: dict[str, pd.DataFrame]) -> dict:
    """Error samples (all runs) per scenario and method."""
    return {label: {METHODS[m]: est.loc[est["method"] == m, "error_m"].to_numpy() for m in METHODS}
            for label, est in estimates.items()}
