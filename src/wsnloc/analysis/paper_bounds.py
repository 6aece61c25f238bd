"""The registry parameters of the papers' filter rows (for their PCRB), and the rows whose
bound and consistency the report plots over time (the papers' main rows).

Consistency rows go to results.csv as table "consistency: <first key>" (a paper table, or
paper C's beacon subset), row <second key> (row label or model), column anees / anis.

Paper A: row label and table (its cells: Table II with motion detection) -> the cell's
parameters (experiments.paper_a.cell_params); main rows: the first hybrid row of both tables.
Paper C: beacon subset and motion model -> experiments.paper_c.cell_params; main rows:
the three models on Table I's beacon subset.
"""

from __future__ import annotations

from typing import Callable

import pandas as pd

from wsnloc.analysis.filter_quality import cell_outputs
from wsnloc.experiments import paper_a, paper_c

PAPER_A_KEYS = ["table", "row"]
PAPER_C_KEYS = ["subset", "model"]


def paper_a_params(spec: dict) -> Callable[[str, str, str], dict]:
    """(scenario label, table, row label) -> resolved parameters of that row of paper A."""
    rows = {paper_a.row_label(row): row for row in spec["rows"]}
    return lambda label, table, row: paper_a.cell_params(spec, label, table, rows[row])


def paper_a_main(spec: dict) -> list[tuple[str, str]]:
    hybrid = [paper_a.row_label(r) for r in spec["rows"] if r["measurements"] == "hybrid"][:1]
    return [(table, row) for table in paper_a.TABLES for row in hybrid]


def paper_c_params(spec: dict) -> Callable[[str, str, str], dict]:
    """(scenario label, beacon subset, model) -> resolved parameters of paper C's cell."""
    return lambda label, subset, model: paper_c.cell_params(spec, label, model, subset)


def paper_c_main(spec: dict) -> list[tuple[str, str]]:
    return [(spec["table_1_subset"], model) for model in paper_c.MODELS]


def paper_bound_outputs(experiment: str, qualities: dict[str, pd.DataFrame], keys: list[str],
                        params_of: Callable[[str, str, str], dict], main: list[tuple[str, str]]) -> tuple[list, list, list]:
    """Over the scenarios (label -> quality rows with `run` and the two keys): consistency
    results rows of every filter row, and the bound and consistency figure panels of the
    main rows (see analysis.filter_quality.cell_outputs)."""
    rows, bound_panels, consistency_panels = [], [], []
    for label, quality in qualities.items():
        for key, group in quality.groupby(keys, sort=False):
            cell_rows, bound, panels = cell_outputs(group, params_of(label, *key), key[1], f"{label}: {key[0]}, {key[1]}",
                                                    experiment=experiment, table=f"consistency: {key[0]}",
                                                    row=key[1], scenario=label)
            rows += cell_rows
            if key in main:
                bound_panels.append(bound)
                consistency_panels += panels
    return rows, bound_panels, consistency_panels
