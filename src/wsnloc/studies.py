"""Studies: scenarios x estimators x anchor subsets, declared in config, run cell by cell.

    studies:
      <study>:
        scenarios: [dataset/scenario, ...]
        subsets: [all, "UWB=9"]               # anchor subsets (default: all)
        parameters: {max_range_m: 60}         # shared by every cell whose estimator has the parameter
        estimators:                           # cell name: parameter overrides
          tracker: {}                         #   the registry entry of the same name
          ekf_slow: {estimator: ekf, accel_sigma_mps2: 0.2}   # or the one named by `estimator`
          tracker_odometry: {estimator: tracker, motion: odometry, scenarios: [mysite/cart]}   # on these only
        overrides:                            # per dataset or dataset/scenario (the more specific wins):
          mysite: {max_range_m: 60}           #   a parameter, for every cell that has it
          mysite/walk: {ekf_slow: {epoch_s: 1.0}}   # or a cell's own parameters

A cell is (study, dataset/scenario, estimator cell); one job per (study, dataset/scenario)
runs all its cells on every run and subset (the runs read once, what the cells derive from
them shared: run_cells), so adding a scenario runs one more job, and adding or changing a
cell re-runs the study's scenario jobs (not the ingest or the papers). Parameters resolve
in this order: registry default < `parameters` < the cell's entry < overrides[dataset] <
overrides[dataset/scenario] (within one, a cell's own mapping after the shared keys). The
papers (wsnloc.experiments) declare their cells the same way.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from wsnloc import diagnosis, results
from wsnloc.analysis.filter_bounds import is_bayesian
from wsnloc.analysis.filter_quality import QUALITY_COLUMNS, cell_outputs, run_quality
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError, WsnlocError, did_you_mean
from wsnloc.estimators import registry
from wsnloc.estimators.range_calibration import model_key
from wsnloc.estimators.run_data import ALL_ANCHORS, RunData
from wsnloc.experiments import calibration
from wsnloc.filters.sliding_window import STATE as SLIDING_WINDOW_STATE
from wsnloc.metrics.tracking import RUN_METRICS, run_metrics, score

EXPERIMENT_PREFIX = "study:"
# a cell's per-epoch bound and consistency values; epoch_update: 1 where the filter updated per epoch
# (its `update: auto` resolved so on that run), else 0 (the NIS of sequential updates gives no ANIS)
QUALITY_TABLE = ["run", "subset"] + QUALITY_COLUMNS + ["epoch_update"]
REPORTED = RUN_METRICS + ("resets", "gated", "time_per_step")   # per cell and run; results.csv: mean and 95% interval
BOUND_METRICS = ("sqrt_pcrb", "efficiency")  # Bayesian filters only
CALIBRATION = ("calibrated_scale", "calibration_fitted", "range_scale", "range_offset")   # where a cell has them
DIAGNOSIS = ("diag_nis_mean", "diag_nis_high", "diag_range_scale", "diag_max_abs_offset_m")   # wsnloc.diagnosis
FINDINGS_SEPARATOR = "\n"      # between a run's diagnosis sentences in metrics.csv and diagnosis.csv
UNIT = {"diag_nis_mean": "per_dof", "diag_nis_high": "per_dof", "diag_range_scale": "1", "n": "count", "availability": "share", "resets": "count", "gated": "share", "efficiency": "ratio",
        "time_per_step": "us", "calibrated_scale": "1", "calibration_fitted": "share", "range_scale": "1"}
# wall-clock time of the estimator per output step (us): measured in the scenario job, so it varies from
# build to build and is left out of byte-reproducibility checks (metric time_per_step_us); a cell after
# the first of its scenario reuses the run's cached products (epochs, fixes, self-fit passes): its
# marginal cost in the study, not its cost alone (benchmarks/ measures that)


CELL_KEYS = ("estimator", "scenarios")     # a cell's keys that are not estimator parameters


def runs_on(spec: dict, cell: str, label: str) -> bool:
    """Whether the cell runs on the dataset/scenario `label`: every scenario of the study unless
    the cell's own `scenarios` names some (e.g. a cell reading odometry only where runs have it)."""
    return label in ((spec["estimators"][cell] or {}).get("scenarios") or spec["scenarios"])


def study_cells(config: dict) -> dict[str, list[tuple[str, str, str]]]:
    """{study: [(dataset, scenario, cell)]}: the jobs of every study (runs_on)."""
    return {study: [(*label.split("/", 1), cell) for label in spec["scenarios"] for cell in spec["estimators"]
                    if runs_on(spec, cell, label)]
            for study, spec in (config.get("studies") or {}).items()}


def estimator_of(spec: dict, cell: str) -> str:
    """The registry entry of a cell: its `estimator` key, else the cell's own name."""
    return (spec["estimators"][cell] or {}).get("estimator", cell)


def cell_params(spec: dict, cell: str, dataset: str, scenario: str, where: str, extra: dict | None = None) -> dict:
    """The resolved parameters of one cell on one dataset/scenario (see the module docstring);
    `extra`: the parameters a paper's table layout sets last (its row's measurements, anchors)."""
    estimator = registry.get(estimator_of(spec, cell), f"{where}.estimators.{cell}.estimator")
    names = {p.name for p in estimator.params}
    merged = {k: v for k, v in (spec.get("parameters") or {}).items() if k in names}
    merged.update({k: v for k, v in (spec["estimators"][cell] or {}).items() if k not in CELL_KEYS})
    for key in (dataset, f"{dataset}/{scenario}"):
        layer = (spec.get("overrides") or {}).get(key) or {}
        merged.update({k: v for k, v in layer.items() if k in names and k not in spec["estimators"]})
        merged.update(layer.get(cell) or {})
    merged.update(extra or {})
    return estimator.resolve(merged, f"{where}.estimators.{cell}")


def check_shared(spec: dict, where: str) -> None:
    """Every key of `parameters` is a parameter of at least one cell's estimator (a misspelt
    shared key would otherwise be ignored)."""
    known = {p.name for c in spec["estimators"]
             for p in registry.get(estimator_of(spec, c), f"{where}.estimators.{c}.estimator").params}
    for name in spec.get("parameters") or {}:
        if name not in known:
            raise ConfigError(f"config key '{where}.parameters.{name}': not a parameter of any of its estimators"
                              f"{did_you_mean(name, known)}")


def validate_studies(config: dict) -> None:
    """Everything knowable before jobs run: estimators, parameters, override keys, subsets."""
    declared = {f"{d}/{s}" for d, spec in config["datasets"].items() for s in spec["scenarios"]}
    campaigns: dict[str, Campaign] = {}
    for study, spec in (config.get("studies") or {}).items():
        where = f"studies.{study}"
        check_shared(spec, where)
        for label in spec["scenarios"]:
            if label not in declared:
                raise ConfigError(f"config key '{where}.scenarios': {label!r} is not a declared dataset/scenario"
                                  f"{did_you_mean(label, declared)} (declared: {', '.join(sorted(declared))})")
        for key, layer in (spec.get("overrides") or {}).items():
            if key not in {d for d in config["datasets"]} | declared:
                raise ConfigError(f"config key '{where}.overrides.{key}': not a declared dataset or dataset/scenario"
                                  f"{did_you_mean(key, set(config['datasets']) | declared)}")
            known = set(spec["estimators"]) | {p.name for c in spec["estimators"]
                                               for p in registry.get(estimator_of(spec, c),
                                                                        f"{where}.estimators.{c}.estimator").params}
            for name in layer or {}:
                if name not in known:
                    raise ConfigError(f"config key '{where}.overrides.{key}.{name}': neither an estimator cell of "
                                      f"this study nor a parameter of its estimators{did_you_mean(name, known)}")
        for cell, entry in spec["estimators"].items():
            for label in (entry or {}).get("scenarios") or []:
                if label not in spec["scenarios"]:
                    raise ConfigError(f"config key '{where}.estimators.{cell}.scenarios': {label!r} is not a "
                                      f"scenario of this study{did_you_mean(label, set(spec['scenarios']))}")
        for label in spec["scenarios"]:
            dataset, scenario = label.split("/", 1)
            for cell in spec["estimators"]:
                if runs_on(spec, cell, label):
                    cell_params(spec, cell, dataset, scenario, where)
            path = config["datasets"][dataset]["campaign"]
            campaign = campaigns.setdefault(path, Campaign.load(path))
            subsets = campaign.spec.get("subsets", {})
            for expression in spec.get("subsets") or [ALL_ANCHORS]:
                missing = [n for n in expression.split("+") if expression != ALL_ANCHORS and n not in subsets]
                if missing:
                    raise ConfigError(f"config key '{where}.subsets': {missing[0]!r} is not a subset of {path} "
                                      f"(has: {', '.join(subsets) or 'none'}; or use 'all')")


# ---- one cell ------------------------------------------------------------------------------
def reads_rss(name: str, p: dict) -> bool:
    return p.get("measurements") in ("rss", "hybrid") or p.get("fixes") in ("rss", "pmix", "fmix") \
        or name in ("pmix", "fmix")


def donor_of(runs: dict[str, dict], donors: dict[str, dict], table: str) -> dict[str, str | None]:
    """The donor of each run: the next run of the scenario with `table` and truth (cyclically),
    or a run of another scenario of the same dataset (`donors`), else None. Never the run itself."""
    pool = {**runs, **donors}
    usable = [k for k, t in pool.items() if len(t.get(table, ())) and len(t["truth"])]
    out = {}
    for i, name in enumerate(runs):
        candidates = [k for k in usable[i + 1:] + usable[:i + 1] if k != name] if name in usable else usable
        out[name] = candidates[0] if candidates else None
    return out


def donor_models(runs: dict[str, dict], donors: dict[str, dict], campaign: Campaign | None, name: str, p: dict,
                 needed: bool) -> dict[str, dict | None]:
    """RSS model of each run fitted on its donor (donor_of; calibration.donor_model_for, estimator
    `name` tracking the donor where the exponent is chosen), else None (configured model)."""
    if not needed or p.get("rss_calibration", "configured") == "configured":
        return {run: None for run in runs}
    pool = {**runs, **donors}

    def fitted(donor: str) -> dict:
        def track(model: dict) -> pd.DataFrame:
            return registry.run(name, RunData(pool[donor], campaign, model, donor), p)
        return dict(calibration.donor_model_for(p, pool[donor]["rss"], pool[donor]["truth"], campaign, track,
                                                pool[donor]["anchors"]), source=f"fitted on {donor}")
    return {run: None if donor is None else fitted(donor) for run, donor in donor_of(runs, donors, "rss").items()}


def range_donor_models(runs: dict[str, dict], donors: dict[str, dict], campaign: Campaign | None,
                       p: dict) -> dict[str, dict | None]:
    """Range scale and per-anchor offsets of each run fitted on its donor (donor_of) when the
    cell asks for `range_calibration: other_run`, else None (the configured values apply)."""
    if p.get("range_calibration") != "other_run":
        return {name: None for name in runs}
    pool = {**runs, **donors}
    return {name: None if donor is None else
            dict(calibration.calibrate_ranges(pool[donor]["ranges"], pool[donor]["truth"], campaign,
                                              pool[donor]["anchors"]), source=f"fitted on {donor}")
            for name, donor in donor_of(runs, donors, "ranges").items()}


def calibration_metrics(estimates: pd.DataFrame) -> dict:
    """Per-run columns of metrics.csv on the range options: gated share, the range calibration
    applied (source; calibration_fitted 1 when fitted on a donor, 0 when the configured values
    stood in; scale; per-anchor offsets as 'A=b;...') and the self-calibrated states."""
    a = estimates.attrs
    source = a.get("range_calibration", "none")
    calibrated = source != "none"
    out = {"gated": a.get("gated_share", 0.0), "range_calibration": a.get("range_calibration", ""),
           "calibrated_scale": a["calibrated_scale"] if calibrated else np.nan,
           "calibration_fitted": float(source.startswith("fitted on")) if calibrated else np.nan,
           "calibrated_offsets_m": ";".join(f"{k}={v:.3f}" for k, v in (a.get("calibrated_offsets_m") or {}).items())}
    out.update({column: a[k] for k, column in (("range_scale", "range_scale"), ("range_offset_m", "range_offset"))
                if k in a})
    return out


def diagnose(data: RunData, p: dict) -> str:
    """Why a run gave no estimates: what the estimator could read."""
    ranges = data.usable_ranges(p.get("preliminary_filter", True), p.get("max_range_m", np.inf))
    members = data.members(p.get("anchors", ALL_ANCHORS))
    ranges = ranges[ranges["anchor_id"].isin(members)]
    rss = data.usable_rss()
    rss = rss[rss["anchor_id"].isin(members)]
    tdoa = data.usable_tdoa()
    reads = "" if not len(tdoa) or p.get("measurements") == "tdoa" else \
        f"; the run has {len(tdoa)} range differences (TDOA), read by the estimators `wsnloc estimators` marks [TDOA]"
    window = ""
    if "window_s" in p and len(ranges) > 1 and p.get("measurements") != "tdoa":   # the sliding window's start
        t = np.sort(ranges["t"].to_numpy(float))
        ends = data.grid(p["epoch_s"], p.get("preliminary_filter", True), p.get("max_range_m", np.inf))
        most = int((np.searchsorted(t, ends, side="right") - np.searchsorted(t, ends - p["window_s"])).max())
        if most < SLIDING_WINDOW_STATE:
            window = (f"; no window of window_s ({p['window_s']:g} s) holds the {SLIDING_WINDOW_STATE} ranges a start "
                      f"needs (at most {most}: about {len(t) / max(t[-1] - t[0], 1e-9):.2g} ranges/s); raise window_s")
    return (f"{len(ranges)} usable ranges from {ranges['anchor_id'].nunique()} anchors and {len(rss)} RSS samples "
            f"from {rss['anchor_id'].nunique()} anchors of subset {p.get('anchors', ALL_ANCHORS)!r}{reads}{window}")


def run_cells(label: str, cells: list[dict], subsets: list[str], runs: dict[str, dict], campaign: Campaign | None,
              donors: dict[str, dict] | None = None) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(estimates, metrics, quality table) of every cell ({cell, estimator, parameters}) of one
    scenario, each with a `cell` column; `runs` holds every table any cell reads. The cells share
    their runs' RunData where they read the same tables with the same calibration, and with it
    its cached products (epochs, fixes, the self-fit's passes)."""
    shared: dict = {}
    estimates, metrics, quality = [], [], []
    for c in cells:
        names = registry.get(c["estimator"]).tables(c["parameters"])
        own = {run: {n: frames[n] for n in names} for run, frames in runs.items()}
        est, met = run_cell(label, c["cell"], c["estimator"], c["parameters"], subsets, own, campaign, donors, shared)
        estimates.append(est.assign(cell=c["cell"]))
        metrics.append(met.assign(cell=c["cell"]))
        quality.append(quality_table(est).assign(cell=c["cell"]))
    return tuple(pd.concat(frames, ignore_index=True) for frames in (estimates, metrics, quality))


def run_cell(label: str, cell: str, name: str, p: dict, subsets: list[str], runs: dict[str, dict],
             campaign: Campaign | None, donors: dict[str, dict] | None = None,
             shared: dict | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(estimates, metrics) of one cell over every run and subset; raises when any yields nothing.

    For a Bayesian filter (but the odometry model) the estimates also carry pcrb_m2 and nees, and
    the metrics sqrt_pcrb and efficiency (analysis.filter_quality). `shared`: RunData of earlier cells of the same
    runs (run_cells), reused when the tables and calibration models are the same."""
    models = donor_models(runs, donors or {}, campaign, name, p, reads_rss(name, p))
    range_models = range_donor_models(runs, donors or {}, campaign, p)
    # no PCRB for the odometry model: its transitions depend on the odometry inputs and the heading
    # along the path, which analysis.filter_bounds does not take (it would bound a random walk instead)
    bayesian = is_bayesian(registry.get(name).function) and p.get("motion") != "odometry"
    shared = {} if shared is None else shared
    estimates, metrics = [], []
    for run, run_tables in runs.items():
        key = (run, tuple(run_tables), model_key(models[run]), model_key(range_models[run]))
        if key not in shared:
            shared[key] = RunData(run_tables, campaign, models[run], f"{label}/{run}", range_models[run])
        data = shared[key]
        for subset in subsets:
            q = dict(p, anchors=subset) if "anchors" in p else p
            started = time.perf_counter()
            est = registry.run(name, data, q)
            elapsed_us = (time.perf_counter() - started) * 1e6
            finite = est[np.isfinite(est["x"]) & np.isfinite(est["y"])]
            if len(finite) == 0:
                raise WsnlocError(f"cell {cell} ({name}) on {label}, {run}, subset {subset!r}: no estimates; "
                                  f"{diagnose(data, dict(p, anchors=subset))}")
            scored = score(est, run_tables["truth"]).assign(run=run, subset=subset)
            efficiency = {}
            if bayesian:
                quality, efficiency = run_quality(data, q, scored)
                scored = scored.join(quality[["pcrb_m2", "nees"]]).assign(
                    epoch_update=float(est.attrs.get("update", q.get("update")) == "epoch"))
            estimates.append(scored)
            diagnosed = diagnosis.diagnose_run(data, est, q)
            metrics.append({"run": run, "subset": subset, **run_metrics(scored, run_tables["truth"]),
                            **diagnosis.metrics_of(diagnosed),
                            "findings": FINDINGS_SEPARATOR.join(diagnosis.findings(diagnosed, q)),
                            "resets": est.attrs.get("resets", 0), "time_per_step": elapsed_us / len(est),
                            **efficiency, **calibration_metrics(est),
                            "rss_model": (models[run] or {}).get("source", "configured") if reads_rss(name, p) else ""})
    return pd.concat(estimates, ignore_index=True), pd.DataFrame(metrics)


# ---- summary ---------------------------------------------------------------------------------
def results_rows(study: str, cell: str, label: str, metrics: pd.DataFrame) -> list[dict]:
    """results.csv rows of one cell: every reported metric, mean over runs with its 95% interval;
    the 3-D RMSE where the run has heights; the fitted range calibration (donor scale, self-calibrated
    scale and offset) where the cell has one;
    the diagnosis (NIS per dof and its band's upper end, range scale and largest per-anchor offset
    against the estimated track) where the run has it. metrics.csv has every diag_* value per run."""
    rows = []
    for subset, group in metrics.groupby("subset", sort=False):
        fitted = [m for m in ("rmse_3d",) + BOUND_METRICS + CALIBRATION + DIAGNOSIS
                  if m in group and pd.to_numeric(group[m], errors="coerce").notna().any()]
        for metric in REPORTED + tuple(fitted):
            rows.append(results.row_over_runs(group[metric], experiment=EXPERIMENT_PREFIX + study, table=subset,
                                              row=cell, column=metric, scenario=label,
                                              metric=f"{metric}_{UNIT.get(metric, 'm')}"))
    return rows



def diagnosis_rows(label: str, cell: str, metrics: pd.DataFrame) -> list[dict]:
    """The diagnosis of each run of one cell (wsnloc.diagnosis.findings: what says the model does not
    fit, each with a likely cause and a remedy, as `wsnloc estimate` prints it): rows scenario,
    cell, run, subset, findings (the sentences joined by FINDINGS_SEPARATOR; empty: none)."""
    return [{"scenario": label, "cell": cell, "run": row["run"], "subset": row["subset"],
             "findings": row["findings"] if isinstance(row.get("findings"), str) else ""}
            for row in metrics.to_dict("records")]


def study_panels(estimates: dict[tuple[str, str], pd.DataFrame]) -> tuple[dict, dict, dict, dict]:
    """Figure panels per scenario: error CDFs over all runs (one curve per cell and subset),
    and, on the first run and subset, the error over time, the tracks beside the truth and, for
    cells with a height estimate and a true height (3-D), z over time beside the true z."""
    cdf, errors, tracks, heights = {}, {}, {}, {}
    for (label, cell), est in estimates.items():
        subsets = list(dict.fromkeys(est["subset"]))
        for subset in subsets:
            name = cell if len(subsets) == 1 else f"{cell} [{subset}]"
            cdf.setdefault(label, {})[name] = est.loc[est["subset"] == subset, "error_m"].to_numpy()
        first = est[(est["run"] == est["run"].iloc[0]) & (est["subset"] == subsets[0])]
        title = f"{label}, {first['run'].iloc[0]}, subset {subsets[0]}"
        errors.setdefault(title, {})[cell] = first[["t", "error_m"]]
        truth = first[["true_x", "true_y"]].rename(columns={"true_x": "x", "true_y": "y"})
        tracks.setdefault(title, (truth, {}))[1][cell] = first
        if {"z", "true_z"} <= set(first.columns):
            true_z = first[["t", "true_z"]].rename(columns={"true_z": "z"}).dropna()
            heights.setdefault(title, (true_z, {}))[1][cell] = first[["t", "z"]]
    return cdf, errors, tracks, heights


def estimator_panels(rows: list[dict], stats) -> dict:
    """Panels of report.figures.estimator_bars from a study's results rows: per scenario, per
    cell (and subset, where the study has several), the `stats` that are position errors in m
    (value, ci95_low, ci95_high)."""
    subsets = {row["table"] for row in rows}
    panels: dict = {}
    for row in rows:
        if row["column"] in stats and row["metric"] == f"{row['column']}_m":
            label = row["row"] if len(subsets) == 1 else f"{row['row']} [{row['table']}]"
            panels.setdefault(row["scenario"], {}).setdefault(label, {})[row["column"]] = (
                row["value"], row["ci95_low"], row["ci95_high"])
    order = [s for s in stats]
    return {title: {label: {s: cells[s] for s in order if s in cells} for label, cells in labels.items()}
            for title, labels in panels.items()}


def quality_table(estimates: pd.DataFrame) -> pd.DataFrame:
    """The QUALITY_TABLE columns of a cell's estimates (empty unless the cell is a Bayesian filter)."""
    if "pcrb_m2" not in estimates:
        return pd.DataFrame({c: pd.Series(dtype=object if c in ("run", "subset") else float) for c in QUALITY_TABLE})
    return estimates.loc[np.isfinite(estimates["x"]) & np.isfinite(estimates["y"]), QUALITY_TABLE]


def bound_summary(study: str, cells: list[dict], qualities: list[pd.DataFrame]) -> tuple[list, list, list]:
    """Over the Bayesian cells (each {label, cell, parameters}) and their quality tables:
    results rows of ANEES / ANIS (metrics.consistency bands), and the panels of the figures
    sqrt(PCRB) beside the RMSE (report.bound_figures.pcrb_panels) and ANEES / ANIS over time
    (consistency_panels), one per cell and subset."""
    rows, bound_panels, consistency_panels = [], [], []
    for cell, quality in zip(cells, qualities):
        for subset, group in quality.groupby("subset", sort=False):
            update = "epoch" if group["epoch_update"].all() else "sequential"        # as the runs resolved it
            cell_rows, bound, panels = cell_outputs(
                group, dict(cell["parameters"], anchors=subset, update=update), cell["cell"],
                f"{cell['label']}: {cell['cell']} [{subset}]",
                experiment=EXPERIMENT_PREFIX + study, table=subset, row=cell["cell"], scenario=cell["label"])
            rows += cell_rows
            bound_panels.append(bound)
            consistency_panels += panels
    return rows, bound_panels, consistency_panels
