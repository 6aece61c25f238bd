"""Paper A (Khan, Sottile, Spirito 2013): EKF with the PV model on UWB TOA ranges, ZigBee
RSS, or both stacked (hybrid), without (Table I) and with (Table II) accelerometer motion
detection, on the Newcom++ scenarios.

Each row (measurement type + anchor subsets) is the registry's `ekf` estimator (PV model,
one update per epoch of `epoch_s`), run without and with motion detection; the RSS model
P0, n, sigma is calibrated on another run with truth (the caller's RunData.rss_model).
This module holds only the paper's table layout, its claims and figures.
"""

from __future__ import annotations

import pandas as pd

from wsnloc import results
from wsnloc.analysis import setup_facts
from wsnloc.estimators import batched
from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import calibration, cells, claims as claims_of
from wsnloc.metrics import verdicts
from wsnloc.metrics.stats import mean_interval
from wsnloc.metrics.tracking import cell_metrics, score

PAPER = "paper_a"
EXPERIMENT = "A"
INPUT_TABLES = ("ranges", "rss", "imu", "truth", "anchors")   # the processed tables a run needs (see load_runs)
MEASUREMENT_LABEL = {"toa": "distance (UWB)", "rss": "RSS (ZigBee)", "hybrid": "hybrid"}
TABLES = cells.CELLS[PAPER]   # the paper's tables "Table I", "Table II": its cells (config estimators)
# detail columns -> results metric; sqrt(PCRB) and efficiency RMSE / sqrt(PCRB) per run; the RMSE over
# the moving epochs (metrics.tracking) shows what the rests add (report: "Why it differs")
DETAIL_METRICS = {"median": "median_m", "p95": "p95_m", "max": "max_m", "rmse_moving": "rmse_moving_m",
                  "sqrt_pcrb": "sqrt_pcrb_m", "efficiency": "efficiency_ratio"}


def anchors_label(row: dict) -> str:
    """A row's anchor subsets as the paper writes them ("UWB=12, ZigBee=21")."""
    return row["anchors"].replace("+", ", ")


def row_label(row: dict) -> str:
    return f"{MEASUREMENT_LABEL[row['measurements']]} | {anchors_label(row)}"


def cell_params(spec: dict, label: str, table: str, row: dict) -> dict:
    """Registry parameters of one row of one table (a cell) on scenario `label`."""
    return cells.params(spec, table, label, PAPER, row)


def run_all(datas: list[RunData], spec: dict, label: str) -> list[pd.DataFrame]:
    """Estimates of every row, without (Table I) and with (Table II) motion detection, scored,
    per run of `datas` (scenario `label`); all runs x rows are stepped together (batched.cell_tracks)."""
    grid = [(row, table) for row in spec["rows"] for table in TABLES]
    params = [cell_params(spec, label, table, row) for row, table in grid]
    tracks = batched.cell_tracks("ekf", [(data, p) for data in datas for p in params], where=cells.where(PAPER))
    labels = {"row": [row_label(row) for row, _ in grid], "table": [table for _, table in grid]}
    return [score(batched.stacked(tracks[i * len(grid):(i + 1) * len(grid)], labels), data.table("truth"))
            for i, data in enumerate(datas)]


def rss_models_for_runs(run_tables: dict[str, dict], campaign: Campaign, spec: dict, label: str) -> dict[str, dict]:
    """RSS model per run (wsnloc.experiments.calibration), fitted on every ZigBee anchor with the
    first cell's parameters (every cell shares rss_calibration)."""
    zigbee = list(campaign.anchors_of("zigbee")["anchor_id"])
    return calibration.rss_models_for_runs(run_tables, campaign, zigbee,
                                           cell_params(spec, label, TABLES[0], spec["rows"][0]))


def evaluate_runs(run_tables: dict[str, dict], campaign: Campaign, spec: dict, label: str) -> pd.DataFrame:
    """Per-run metrics (run_metrics, column `run`) of every cell on runs given as tables (e.g.
    extra simulated runs of scenario `label`), each run's RSS model as in the workflow
    (rss_models_for_runs)."""
    models = rss_models_for_runs(run_tables, campaign, spec, label)
    estimates = run_all([RunData(tables, campaign, models[name], name) for name, tables in run_tables.items()],
                        spec, label)
    return pd.concat([run_metrics(est, tables["truth"]).assign(run=name)
                      for (name, tables), est in zip(run_tables.items(), estimates)], ignore_index=True)


def run(data: RunData, spec: dict, label: str) -> pd.DataFrame:
    """run_all of one run."""
    return run_all([data], spec, label)[0]


def run_metrics(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per (table, row): the standard run metrics (metrics.tracking) and the mean NIS."""
    metrics = cell_metrics(estimates, ["table", "row"], truth)
    metrics["nis_mean"] = estimates.groupby(["table", "row"], sort=False)["nis"].mean().to_numpy()
    return metrics


def paper_value(paper: dict, row: dict, table: str, motion: str):
    for published in paper["rmse_m"]:
        if published["row"] == MEASUREMENT_LABEL[row["measurements"]] and published["anchors"] == anchors_label(row):
            return published[f"{'I' if table == 'Table I' else 'II'}_{motion}"]
    return None


def results_rows(metrics: pd.DataFrame, scenario: str, motion: str, spec: dict, paper: dict) -> list[dict]:
    out = []
    for table in TABLES:
        for row in spec["rows"]:
            sel = metrics[(metrics["table"] == table) & (metrics["row"] == row_label(row))]
            out.append(results.row_over_runs(sel["rmse"], experiment=EXPERIMENT, table=table, row=row_label(row),
                                             column=motion, scenario=scenario, metric="rmse_m",
                                             paper_value=paper_value(paper, row, table, motion)))
            for metric, name in DETAIL_METRICS.items():
                if metric in sel:   # the bound columns: metrics written with the PCRB (analysis.filter_quality)
                    out.append(results.row_over_runs(sel[metric], experiment=EXPERIMENT, table=f"{table} detail",
                                                     row=row_label(row), column=metric, scenario=scenario, metric=name))
    return out


def claims(metrics: dict[str, pd.DataFrame], motions: dict[str, str], spec: dict) -> list[dict]:
    """Paper A's claims decided on per-run RMSE (experiments.claims): metrics[label] is a
    scenario's per-run metrics.csv, motions[label] its speed profile (constant / variable).

    Rows and tables of one scenario share their runs (paired); constant against variable
    compares two scenarios (independent runs, Welch interval).
    """
    by_kind = {kind: [row_label(r) for r in spec["rows"] if r["measurements"] == kind] for kind in MEASUREMENT_LABEL}
    labels = [row_label(r) for r in spec["rows"]]
    tables = TABLES

    def rmse(label, table, row, metric="rmse"):
        return claims_of.runs_of(metrics[label], metric, table=table, row=row)

    order, anchors, detection = [], [], []
    for label in metrics:
        where = f"{label} "
        for table in tables:
            for hybrid, toa, rss in zip(by_kind["hybrid"], by_kind["toa"], by_kind["rss"]):
                for lo, hi in ((hybrid, toa), (toa, rss)):
                    order.append(claims_of.paired(rmse(label, table, lo), rmse(label, table, hi), "<",
                                                  f"{where}{table}: {lo} - {hi}"))
            for kind, rows in by_kind.items():
                if len(rows) == 2:
                    anchors.append(claims_of.paired(rmse(label, table, rows[0]), rmse(label, table, rows[1]), "<",
                                                    f"{where}{table}: {rows[0]} - {rows[1]}"))
        for row in labels:
            detection.append(claims_of.paired(rmse(label, "Table II", row), rmse(label, "Table I", row), "<",
                                              f"{where}{row}: with - without motion detection"))
    speed = []
    constant = [label for label in metrics if motions[label] == "constant"]
    variable = [label for label in metrics if motions[label] == "variable"]
    for c, v in zip(constant, variable):
        for table in tables:
            for row in labels:
                # moving epochs only (metrics.tracking: rmse_moving): the rests' share would decide it otherwise
                speed.append(claims_of.unpaired(rmse(c, table, row, "rmse_moving"), rmse(v, table, row, "rmse_moving"),
                                                "<", f"{table} {row}: {c} - {v}, moving epochs (independent runs)"))
    return [claims_of.record("Hybrid beats TOA-only, which beats RSS-only", verdicts.claim(order)),
            claims_of.record("More anchors give a lower RMSE", verdicts.claim(anchors)),
            claims_of.record("Constant speed is tracked better than variable speed", verdicts.claim(speed),
                             note="RMSE over the epochs at which the cart moves: "),
            claims_of.record("Motion detection improves every row", verdicts.claim(detection))]


# Set-up facts: the measurements the filter of Table I's first TOA / RSS row used per epoch (its n_meas,
# after the preliminary filter and range limit), not the anchors the logs hold (pl0_sensitivity counts those)
MEASUREMENTS_USED = {"toa": "UWB ranges the TOA filter used per epoch", "rss": "ZigBee RSS the RSS filter used per epoch"}


def setup_rows(estimates: dict[str, pd.DataFrame], spec: dict) -> list[dict]:
    """Set-up facts per scenario (analysis.setup_facts) on Table I's first TOA and RSS rows:
    the static share of epochs and the measurements used per epoch (MEASUREMENTS_USED); then
    the measurements used per epoch of every TOA and RSS row, named with its anchor subset
    (subset_fact: "<fact> (UWB=9)")."""
    first = {kind: next((row_label(r) for r in spec["rows"] if r["measurements"] == kind), None)
             for kind in ("toa", "rss")}
    rows = []
    for label, est in estimates.items():
        plain = est[est["table"] == "Table I"]
        cells = {kind: plain[plain["row"] == row] for kind, row in first.items() if row}
        if cells:
            rows.append(setup_facts.fact_row(EXPERIMENT, "static share of epochs", label,
                                             setup_facts.static_share(next(iter(cells.values()))), "share"))
        for kind, name in MEASUREMENTS_USED.items():
            if kind in cells:
                rows.append(setup_facts.fact_row(EXPERIMENT, name, label,
                                                 setup_facts.measurements_per_epoch(cells[kind]), "count"))
        for r in spec["rows"]:
            if r["measurements"] in MEASUREMENTS_USED:
                rows.append(setup_facts.fact_row(
                    EXPERIMENT, subset_fact(MEASUREMENTS_USED[r["measurements"]], r["anchors"]), label,
                    setup_facts.measurements_per_epoch(plain[plain["row"] == row_label(r)]), "count"))
    return rows


def subset_fact(fact: str, subset: str) -> str:
    """The name of a set-up fact measured on one anchor subset ("UWB=9"): "<fact> (<subset>)"."""
    return f"{fact} ({subset})"


STATIC_TABLE = "Table II gain against static share"


def static_sweep_rows(sweep: pd.DataFrame, scenario: str) -> list[dict]:
    """results rows of the static-share sweep (analysis.static_share): per final rest the
    static share of the epochs and the Table II - Table I RMSE of the hybrid row (m)."""
    rows = []
    for rest, group in sweep.groupby("rest_s", sort=True):
        column = f"final rest {rest:g} s"
        rows += [results.row_over_runs(group["static_share"], experiment=EXPERIMENT, table=STATIC_TABLE,
                                       row="static share of epochs", column=column, scenario=scenario, metric="share"),
                 results.row_over_runs(group["gain_m"], experiment=EXPERIMENT, table=STATIC_TABLE,
                                       row="hybrid: Table II - Table I", column=column, scenario=scenario,
                                       metric="rmse_gain_m")]
    return rows


def static_sweep_curve(sweep: pd.DataFrame) -> pd.DataFrame:
    """Gain (m, mean and 95% interval over runs: metrics.stats.mean_interval, none with fewer than
    MIN_INTERVAL_RUNS runs) against the mean static share, per final rest."""
    points = [(group["static_share"].mean(), *mean_interval(group["gain_m"])) for _, group in sweep.groupby("rest_s")]
    return pd.DataFrame(sorted(points), columns=["x", "value", "ci95_low", "ci95_high"])


def paper_gains(paper: dict, spec: dict) -> dict[str, float]:
    """The paper's Table II - Table I RMSE of the first hybrid row, per speed profile (m)."""
    hybrid = next((r for r in spec["rows"] if r["measurements"] == "hybrid"), None)
    if hybrid is None:
        return {}
    return {motion: paper_value(paper, hybrid, "Table II", motion) - paper_value(paper, hybrid, "Table I", motion)
            for motion in ("constant", "variable")
            if paper_value(paper, hybrid, "Table I", motion) is not None}


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


def anchor_curves(res: pd.DataFrame, spec: dict) -> dict:
    """Table I RMSE against the number of anchors, per measurement type and scenario."""
    sel = res[(res["experiment"] == EXPERIMENT) & (res["table"] == "Table I") & (res["metric"] == "rmse_m")]
    curves = {}
    for row in spec["rows"]:
        count = sum(int(subset.split("=")[1]) for subset in row["anchors"].split("+"))
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
