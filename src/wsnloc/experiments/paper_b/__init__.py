"""Paper B (Pavia group, c. 2013): UWB Min-Max fixes fused with inertial dead reckoning
by a steady-state Kalman filter, beside the classical (time-varying gain) KF.

Every method is a registry estimator: `minmax` (UWB Min-Max fixes at every 2 Hz epoch),
`dead_reckoning` (5 Hz IMU from the known start pose), and `dr_sskf` / `dr_kf` (both
filters predict with each 5 Hz step's dead-reckoning displacement and update with the
fix that arrived during the step). This module holds only the paper's table layout,
its claims and figures.
"""

from __future__ import annotations

import pandas as pd

from wsnloc import results
from wsnloc.analysis import setup_facts
from wsnloc.campaign import Campaign
from wsnloc.estimators import batched
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import cells, claims as claims_of
from wsnloc.metrics import verdicts
from wsnloc.metrics.tracking import cell_metrics, score
from wsnloc.signal.resample import resample_imu

PAPER = "paper_b"
EXPERIMENT = "B"
INPUT_TABLES = ("ranges", "rss", "truth", "anchors", "imu_5hz")   # the processed tables a run needs (see load_runs)
# The paper's methods: its cells (config experiments.paper_b.estimators) and their row labels.
METHODS = dict(zip(cells.CELLS[PAPER], ("UWB only (Min-Max)", "IMU only (dead reckoning)", "steady-state KF fusion",
                                        "classical KF fusion")))   # uwb, imu, sskf, kf


def run(data: RunData, spec: dict, label: str, methods=tuple(METHODS)) -> pd.DataFrame:
    """UWB-only, IMU-only, steady-state KF and classical KF positions of one run of scenario
    `label` (or the given methods), scored."""
    tracks = []
    for method in methods:
        tracks += batched.cell_tracks(cells.estimator(spec, method),
                                      [(data, cells.params(spec, method, label, PAPER))], where=cells.where(PAPER))
    return score(batched.stacked(tracks, {"method": list(methods)}, ("t", "x", "y")), data.table("truth"))


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    return cell_metrics(estimates, ["method"], truth)


def evaluate_runs(run_tables: dict[str, dict], campaign: Campaign, spec: dict, label: str,
                  resample: dict) -> pd.DataFrame:
    """Per-run metrics of the four methods on runs given as raw-rate tables (e.g. extra
    simulated runs of scenario `label`), their IMU resampled with the workflow's `resample` settings."""
    frames = []
    for name, tables in run_tables.items():
        data = RunData(dict(tables, imu_5hz=resample_imu(tables["imu"], **resample)), campaign, None, name)
        frames.append(run_metrics(run(data, spec, label), tables["truth"]).assign(run=name))
    return pd.concat(frames, ignore_index=True)


def results_rows(metrics: pd.DataFrame, scenario: str, paper: dict, simulated_setup: bool) -> list[dict]:
    """RMSE and max error per method; the paper's simulation or real-data value beside ours."""
    published = {row["row"]: row for row in paper["rmse_m"]}
    rows = []
    for method, label in METHODS.items():
        sel = metrics[metrics["method"] == method]
        ref = published.get(label, {})
        rmse_paper = ref.get("simulation" if simulated_setup else "real")
        max_paper = None if simulated_setup else ref.get("max_real")
        # seed 001 §V.B: "20 simulations were performed for each setup", "the average RMSE": a mean;
        # §V.C: the real dataset is one run
        rows.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table="RMSE", row=label,
                                          column=scenario, scenario=scenario, metric="rmse_m",
                                          paper_value=rmse_paper, paper_is_mean=simulated_setup))
        rows.append(results.row_over_runs(sel["max"], experiment=EXPERIMENT, table="Max error", row=label,
                                          column=scenario, scenario=scenario, metric="max_m",
                                          paper_value=max_paper if isinstance(max_paper, (int, float)) else None))
        for metric in ("median", "p95"):
            rows.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table="Detail", row=label,
                                              column=metric, scenario=scenario, metric=f"{metric}_m"))
    return rows


def claims(metrics: dict[str, pd.DataFrame]) -> list[dict]:
    """Paper B's claims decided on per-run RMSE (experiments.claims), paired within each
    scenario (metrics[label] is its per-run metrics.csv)."""
    fusion, classical = [], []
    for label, per_run in metrics.items():
        rmse = {m: claims_of.runs_of(per_run, method=m) for m in METHODS}
        fusion += [claims_of.paired(rmse["sskf"], rmse[other], "<", f"{label}: steady-state KF - {name}")
                   for other, name in (("uwb", "UWB only"), ("imu", "IMU only"))]
        classical.append(claims_of.paired(rmse["kf"], rmse["sskf"], "<", f"{label}: classical - steady-state KF"))
    return [claims_of.record("Fusion beats both UWB only and IMU only", verdicts.claim(fusion)),
            claims_of.record("The classical KF is somewhat better than the steady-state KF", verdicts.claim(classical))]


def setup_rows(estimates: dict[str, pd.DataFrame], spec: dict) -> list[dict]:
    """Set-up facts per scenario (analysis.setup_facts): the static share of the 5 Hz epochs and
    the rest (s) the dead reckoning measures its IMU biases over (BIAS_CALIBRATION; 0: none,
    whatever rests the scenario has)."""
    rows = []
    for label, est in estimates.items():
        cell = est[est["method"] == "sskf"]
        rows.append(setup_facts.fact_row(EXPERIMENT, "static share of epochs", label, setup_facts.static_share(cell),
                                         "share"))
        calibration = float(cells.params(spec, "imu", label, PAPER)["static_start_s"])
        rows.append(setup_facts.fact_row(EXPERIMENT, setup_facts.BIAS_CALIBRATION, label,
                                         pd.Series(calibration, index=sorted(set(cell["run"]))), "seconds"))
    return rows


SNR_TABLE = "Dead reckoning RMSE against accelerometer SNR"


def snr_rows(curve: pd.DataFrame, scenario: str, paper: dict) -> list[dict]:
    """results rows of the dead-reckoning RMSE (m) per accelerometer SNR (analysis.imu_snr
    on `scenario`); the paper's simulated IMU-only RMSE beside its 60 dB."""
    published = {row["row"]: row for row in paper["rmse_m"]}.get(METHODS["imu"], {}).get("simulation")
    return [results.row_over_runs(r.run_rmse_m, experiment=EXPERIMENT, table=SNR_TABLE, row=METHODS["imu"],
                                  column=f"{r.snr_db:g} dB", scenario=scenario, metric="rmse_m",
                                  paper_value=published if r.snr_db == 60 else None, paper_is_mean=True)
            for r in curve.itertuples()]


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
