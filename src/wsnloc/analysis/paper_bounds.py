"""The registry parameters of the papers' filter rows (for their PCRB), and the rows whose
bound and consistency the report plots over time (the papers' main rows).

Consistency rows go to results.csv as table "consistency: <first key>" (a paper table, or
paper C's beacon subset), row <second key> (row label or model), column anees / anis.

Paper A: row label and table (Table II: motion detection) -> the `ekf` parameters of
experiments.paper_a.estimator_params; main rows: the first hybrid row of Tables I and II.
Paper C: beacon subset and motion model -> experiments.paper_c.estimator_params; main rows:
the three models on Table I's beacon subset.
"""

from __future__ import annotations

from typing import Callable

import pandas as pd

from wsnloc.analysis.filter_quality import cell_outputs
from wsnloc.estimators import registry
from wsnloc.experiments import paper_a, paper_c

PAPER_A_KEYS = ["table", "row"]
PAPER_C_KEYS = ["subset", "model"]


def paper_a_params(settings: paper_a.Settings) -> Callable[[str, str], dict]:
    """(table, row label) -> resolved `ekf` parameters of that row of paper A."""
    rows = {paper_a.row_label(row): row for row in settings.rows}
    return lambda table, row: registry.get("ekf").resolve(
        paper_a.estimator_params(settings, rows[row], table == "Table II"), "experiments.paper_a")


def paper_a_main(settings: paper_a.Settings) -> list[tuple[str, str]]:
    hybrid = [paper_a.row_label(r) for r in settings.rows if r["measurements"] == "hybrid"][:1]
    return [(table, row) for table in ("Table I", "Table II") for row in hybrid]


def paper_c_params(settings: paper_c.Settings) -> Callable[[str, str], dict]:
    """(beacon subset, model) -> resolved `ekf` parameters of paper C."""
    return lambda subset, model: registry.get("ekf").resolve(paper_c.estimator_params(settings, model, subset),
                                                             "experiments.paper_c")


def paper_c_main(settings: paper_c.Settings) -> list[tuple[str, str]]:
    return [(settings.table_1_subset, model) for model in paper_c.MODELS]


def paper_bound_outputs(experiment: str, qualities: dict[str, pd.DataFrame], keys: list[str],
                        params_of: Callable[[str, str], dict], main: list[tuple[str, str]]) -> tuple[list, list, list]:
    """Over the scenarios (label -> quality rows with `run` and the two keys): consistency
    results rows of every filter row, and the bound and consistency figure panels of the
    main rows (see analysis.filter_quality.cell_outputs)."""
    rows, bound_panels, consistency_panels = [], [], []
    for label, quality in qualities.items():
        for key, group in quality.groupby(keys, sort=False):
            cell_rows, bound, panels = cell_outputs(group, params_of(*key), key[1], f"{label}: {key[0]}, {key[1]}",
                                                    experiment=experiment, table=f"consistency: {key[0]}",
                                                    row=key[1], scenario=label)
            rows += cell_rows
            if key in main:
                bound_panels.append(bound)
                consistency_panels += panels
    return rows, bound_panels, consistency_panels
