"""A paper's cells: registry estimators declared in config like a study's (wsnloc.studies).

    experiments.paper_x:
      scenarios: [dataset/scenario, ...]
      parameters: {epoch_s: 0.5}               # shared by every cell whose estimator has them
      estimators:                              # the cells: registry estimator and own overrides
        PV: {estimator: ekf, motion: pv}
      overrides: {dataset/scenario: {...}}     # per dataset or scenario, as in a study

A cell's parameters resolve as a study cell's (studies.cell_params), then the paper's table
layout sets the parameters it varies (a row's measurements and anchors: `extra`). Nothing
else names a parameter: every default is the registry's.
"""

from __future__ import annotations

from wsnloc.errors import ConfigError
from wsnloc.estimators import registry
from wsnloc.studies import cell_params, check_shared, estimator_of

# The cells each paper's layout and claims name (its modules' constants): config must declare these.
CELLS = {"paper_a": ("Table I", "Table II"), "paper_b": ("uwb", "imu", "sskf", "kf"), "paper_c": ("P", "PV", "PVA"),
         "paper_d": ("velocity", "kalman")}


def where(paper: str) -> str:
    """The config key of a paper ("paper_c" -> "experiments.paper_c"), for error messages."""
    return f"experiments.{paper}"


def params(spec: dict, cell: str, label: str, paper: str, extra: dict | None = None) -> dict:
    """Resolved registry parameters of one cell on the scenario `label` (dataset/scenario)."""
    dataset, scenario = label.split("/", 1)
    return cell_params(spec, cell, dataset, scenario, where(paper), extra)


def layout_params(spec: dict, name: str, label: str, paper: str, extra: dict) -> dict:
    """Resolved parameters of a cell the paper's table layout implies (registry estimator `name`,
    e.g. paper D's localizers): the paper's `parameters` and `overrides`, then `extra`."""
    implied = {"parameters": spec.get("parameters") or {}, "estimators": {name: None},
               "overrides": spec.get("overrides") or {}}
    return params(implied, name, label, paper, extra)


def estimator(spec: dict, cell: str) -> str:
    """The registry estimator of a cell (its `estimator` key, else its name)."""
    return estimator_of(spec, cell)


def acted_on(spec: dict, sigma: str) -> list[str]:
    """The cells a sensitivity sigma acts on: `cell.parameter` names one cell; a key of
    `parameters` acts on every cell whose estimator has it and that does not set its own."""
    cell, _, name = sigma.rpartition(".")
    if cell:
        return [cell]
    return [c for c in spec["estimators"]
            if name in {p.name for p in registry.get(estimator(spec, c)).params}
            and name not in (spec["estimators"][c] or {})]


def check(spec: dict, paper: str) -> None:
    """Before any job: the paper declares the cells its layout names (CELLS), its shared
    parameters belong to some cell, its sensitivity sigmas name numbers it sets, and every
    cell resolves on every scenario (registry names, types and ranges; overrides)."""
    declared, expected = list(spec["estimators"]), list(CELLS[paper])
    if sorted(declared) != sorted(expected):
        raise ConfigError(f"config key '{where(paper)}.estimators': the paper's tables and claims name the cells "
                          f"{expected}; declared: {declared}")
    check_shared(spec, where(paper))
    labels = list(spec["scenarios"]) + list(spec.get("simulation_scenarios", []))
    known = set(labels) | {label.split("/", 1)[0] for label in labels}
    for key in spec.get("overrides") or {}:
        if key not in known:
            raise ConfigError(f"config key '{where(paper)}.overrides.{key}': not a dataset or dataset/scenario the "
                              f"paper runs on ({', '.join(labels)})")
    from wsnloc.experiments.sensitivity import variants   # its sigmas name numbers of the paper's cells

    variants(spec, where(paper))
    for label in labels:
        for cell in declared:
            params(spec, cell, label, paper)
