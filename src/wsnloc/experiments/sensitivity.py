"""Sensitivity of a paper's claim verdicts to its a-priori filter settings.

Config `experiments.paper_x.sensitivity`: `sigmas` (the paper's a-priori noise sigmas: a
key of its `parameters`, e.g. "range_sigma_m", or `cell.parameter`, e.g.
"kalman.accel_sigma_mps2"), `factors` (e.g. [0.5, 2]) and `runs` (the first `runs` Monte
Carlo runs of each scenario; 0 turns it off).
One sigma is scaled at a time: setting "range_sigma_m x0.5" is the paper's configuration
with range_sigma_m halved. The paper's job re-runs its estimators on those runs of each
scenario for every setting (the runs already loaded for the main tables); the baseline "x1"
is the main per-run metrics of the same runs. The same job then decides every claim per
setting (experiments.claims) and writes results rows:
  table "Sensitivity", row = claim, column = setting, metric "verdict",
  value = claims.VERDICT_CODE (+1 holds, 0 inconclusive, -1 does not hold), runs = runs used.
A verdict is robust when it is the same at every setting, baseline included.
"""

from __future__ import annotations

import copy
from typing import Callable

import pandas as pd

from wsnloc.errors import ConfigError
from wsnloc.experiments import claims as claims_of

BASELINE = "x1"
TABLE = "Sensitivity"


def setting_label(sigma: str, factor: float) -> str:
    return f"{sigma} x{factor:g}"


def _value(spec: dict, sigma: str):
    """The configured value of a sigma: `cell.parameter` from the cell's entry, else the paper's
    shared `parameters` (which the cell inherits); a shared key from `parameters`. None when unset."""
    cell, _, name = sigma.rpartition(".")
    own = (spec.get("estimators") or {}).get(cell) or {} if cell else {}
    return own.get(name, (spec.get("parameters") or {}).get(name))


def _override_targets(spec: dict, sigma: str) -> list[dict]:
    """The per-dataset/scenario override entries that set the sigma (a number): `cell.parameter` in
    a layer's cell entry, a shared key in the layer itself."""
    cell, _, name = sigma.rpartition(".")
    out = []
    for layer in (spec.get("overrides") or {}).values():
        target = (layer or {}).get(cell) if cell else layer
        if isinstance(target, dict) and isinstance(target.get(name), (int, float)):
            out.append(target)
    return out


def variants(spec: dict, where: str) -> list[tuple[str, str, dict]]:
    """(setting label, sigma, the paper's config with that sigma scaled) for every sigma and factor:
    a shared key scaled in `parameters`, `cell.parameter` set in that cell's entry; the values the
    paper's `overrides` set for it per dataset or scenario (e.g. paper C's P sigma per speed) are
    scaled by the same factor.

    `where` is the paper's config key (e.g. "experiments.paper_a"), for error messages.
    """
    grid = spec.get("sensitivity") or {}
    if not grid.get("runs"):
        return []
    out = []
    for i, sigma in enumerate(grid.get("sigmas", [])):
        value = _value(spec, sigma)
        cell, _, name = sigma.rpartition(".")
        overridden = _override_targets(spec, sigma)
        if value is None and overridden and (not cell or cell in spec["estimators"]):
            value = None                       # set per scenario only: scaled there below
        elif not isinstance(value, (int, float)) or isinstance(value, bool) or (cell and cell not in spec["estimators"]):
            raise ConfigError(f"config key '{where}.sensitivity.sigmas.{i}': {sigma!r} is neither a number in "
                              f"{where}.parameters nor 'cell.parameter' of a cell with that number set (in its "
                              f"entry or in parameters)")
        for factor in grid["factors"]:
            scaled = copy.deepcopy(spec)
            if value is not None:
                target = scaled.setdefault("estimators", {})[cell] if cell else scaled.setdefault("parameters", {})
                if cell and target is None:
                    target = scaled["estimators"][cell] = {}
                target[name] = value * factor
            for target in _override_targets(scaled, sigma):
                target[name] = target[name] * factor
            out.append((setting_label(sigma, factor), sigma, scaled))
    return out


def sample_runs(spec: dict, run_names) -> list[str]:
    """The runs the grid is evaluated on: the first `sensitivity.runs` in run order."""
    grid = spec.get("sensitivity") or {}
    return sorted(run_names)[: int(grid.get("runs") or 0)]


def grid_metrics(spec: dict, where: str, metrics: pd.DataFrame,
                 evaluate: Callable[[dict, str, list[str]], pd.DataFrame]) -> pd.DataFrame:
    """Per-run metrics of every setting on the sampled runs, with columns `setting`, `sigma`
    (the scaled key, "" for the baseline) and `factor` (1 for the baseline).

    metrics: the main per-run metrics (baseline); evaluate(variant_spec, sigma, runs) -> those
    runs' metrics (column `run`) under the variant (the caller's estimators on the already
    loaded runs, all runs at once where it batches them, else `each_run`; `sigma` lets it
    re-run only the cells the scaled sigma acts on: experiments.cells.acted_on, `replace_cells`).
    """
    grid = variants(spec, where)
    runs = sample_runs(spec, metrics["run"].unique())
    frames = [metrics[metrics["run"].isin(runs)].assign(setting=BASELINE, sigma="", factor=1.0)]
    factors = [f for _ in (spec.get("sensitivity") or {}).get("sigmas", []) for f in spec["sensitivity"]["factors"]]
    for (label, sigma, variant), factor in zip(grid, factors):
        if runs:
            frames.append(evaluate(variant, sigma, runs).assign(setting=label, sigma=sigma, factor=float(factor)))
    return pd.concat(frames, ignore_index=True)


def each_run(evaluate_one: Callable[[dict, str, str], pd.DataFrame]) -> Callable[[dict, str, list[str]], pd.DataFrame]:
    """grid_metrics' evaluate from a per-run evaluate_one(variant_spec, sigma, run) -> that run's metrics."""
    return lambda variant, sigma, runs: pd.concat([evaluate_one(variant, sigma, run).assign(run=run) for run in runs],
                                                  ignore_index=True)


def replace_cells(metrics: pd.DataFrame, run: str, rerun: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """One run's baseline metrics with the re-run cells (matched on the `keys` columns) replaced."""
    done = set(map(tuple, rerun[keys].to_numpy()))
    base = metrics[metrics["run"] == run].drop(columns="run")
    kept = base[[tuple(cell) not in done for cell in base[keys].to_numpy()]]
    return pd.concat([kept, rerun], ignore_index=True)


def results_rows(experiment: str, grids: dict[str, pd.DataFrame], decide: Callable[[dict], list[dict]],
                 table: str = TABLE) -> list[dict]:
    """Every claim's verdict at every setting, in results table `table`: grids[scenario label] is
    that scenario's sensitivity.csv; decide(per-run metrics by scenario label) -> claims records."""
    if not grids or any(grid.empty for grid in grids.values()):
        return []
    settings = list(dict.fromkeys(s for grid in grids.values() for s in grid["setting"]))
    split = {label: dict(tuple(grid.groupby("setting", sort=False))) for label, grid in grids.items()}
    rows = []
    for setting in settings:
        for rec in decide({label: by_setting.get(setting, grids[label].iloc[:0])
                           for label, by_setting in split.items()}):
            rows.append({"experiment": experiment, "table": table, "row": rec["claim"], "column": setting,
                         "scenario": "all", "metric": "verdict", "value": claims_of.VERDICT_CODE[rec["verdict"]],
                         "ci95_low": None, "ci95_high": None,
                         "runs": min((p["runs"] for p in rec["parts"]), default=None), "paper_value": None})
    return rows
