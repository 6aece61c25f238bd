"""Report sections for the papers: tables in the papers' layout, claims, figures.

A paper table is {title, scenario, columns, rows: [{label, cells: [cell]}]} where a cell
holds our value with its 95% interval (or, for ANEES / ANIS, its chi-square band) and the
paper's value (None when unpublished).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.experiments import claims as claims_of
from wsnloc.metrics.verdicts import VERDICTS, paper_value_inside


def cell_of(results: pd.DataFrame, **keys) -> dict:
    """The first row of `results` where every key column equals its value, as a table cell;
    rows and columns are indexed once per frame (claims.cell_rows, claims.column_values)."""
    rows = claims_of.cell_rows(results, tuple(keys)).get(tuple(keys.values()))
    if rows is None:
        return {"value": None, "low": None, "high": None, "band_low": None, "band_high": None, "runs": None,
                "paper": None, "delta": None, "inside": False, "basis": "mean", "scenario": None}
    paper, value, low, high, band_low, band_high, runs = (
        _present(results, column, int(rows[0]))
        for column in ("paper_value", "value", "ci95_low", "ci95_high", "band_low", "band_high", "runs"))
    # A single published run against our per-run band, a published mean against our mean's interval
    # (results module docstring).
    basis = "run" if band_low is not None and paper is not None else "mean"
    ref_low, ref_high = (band_low, band_high) if basis == "run" else (low, high)
    inside = paper_value_inside(paper, np.nan if ref_low is None else ref_low, np.nan if ref_high is None else ref_high)
    # The red/green difference only where the paper's value lies outside the interval it is compared with.
    delta = value - paper if value is not None and paper is not None and not inside else None
    return {"value": value, "low": low, "high": high, "band_low": band_low, "band_high": band_high,
            "runs": int(runs) if runs is not None else None, "paper": paper, "delta": delta, "inside": inside,
            "basis": basis, "scenario": _present(results, "scenario", int(rows[0])) if "scenario" in results else None}


def _present(results: pd.DataFrame, column: str, row: int):
    """results[column] at position `row`, None where missing."""
    value = claims_of.column_values(results, column)[row]
    return value if pd.notna(value) else None


def paper_table(results: pd.DataFrame, *, experiment: str, table: str, scenario: str, rows: list[str],
                columns: list[str], metric: str, title: str) -> dict:
    return {
        "title": title, "scenario": scenario, "columns": columns,
        "rows": [{"label": r, "cells": [cell_of(results, experiment=experiment, table=table, scenario=scenario,
                                              row=r, column=c, metric=metric) for c in columns]} for r in rows],
    }


def detail_table(results: pd.DataFrame, *, experiment: str, table: str, scenario: str, rows: list[str],
                 columns: list[str], metrics: list[str]) -> dict:
    """Median, percentiles, max (and availability) per cell: one line per (row, column)."""
    lines = []
    for r in rows:
        for c in columns:
            cells = [cell_of(results, experiment=experiment, table=table, scenario=scenario, row=r, column=c, metric=m)
                     for m in metrics]
            lines.append({"label": f"{r} / {c}", "cells": cells})
    return {"title": f"{table} detail, {scenario}", "metrics": metrics, "lines": lines}





def paper_section(experiment: str, paper: dict, spec: dict, claims: dict, figures: dict[str, str],
                  numbers=None, paper_terms=None, **parts) -> dict:
    """The context every paper section has (paper.html.j2): id, title and citation (config/papers.yaml),
    whether its tables are published, its config `spec`, claims and figures, its set-up note's
    template (section.html.j2 of its package) and `parts`: tables, details, bounds, cost, why,
    setup (the resolved parameters its note shows). With `numbers` (explanations.Numbers), "why"
    gets one computed sentence per table cell outside our interval (explanations.cell_whys, with
    the paper's own `paper_terms`)."""
    if numbers is not None:
        from wsnloc.report.explanations import cell_whys

        parts["why"] = [*parts.get("why", []), *cell_whys(numbers, experiment, parts.get("tables", []),
                                                                   paper_terms)]
    return {"id": experiment, "title": paper["title"], "citation": paper["citation"],
            "published": bool(paper.get("tables_published", True)), "spec": spec, "claims": claims["claims"],
            "figures": figures, "partial": f"paper_{experiment.lower()}/section.html.j2",
            **{"tables": [], "details": [], "bounds": [], "cost": [], "why": [], **parts}}


def grid_table(results: pd.DataFrame, *, experiment: str, table: str, rows: list[str], columns: list[str],
               metric: str, title: str, scenario: str = "") -> dict:
    """A paper table whose cells are found by (table, row, column) across scenarios; `table` (the
    results.csv table) is kept for the look-ups of its detail rows (explanations.contributions)."""
    sel = results[(results["experiment"] == experiment) & (results["table"] == table)]
    return {"title": title, "scenario": scenario, "columns": columns, "table": table,
            "rows": [{"label": r, "cells": [cell_of(sel, row=r, column=c, metric=metric) for c in columns]} for r in rows]}


def columns_of(results: pd.DataFrame, experiment: str, table: str) -> list[str]:
    sel = results[(results["experiment"] == experiment) & (results["table"] == table)]
    return list(dict.fromkeys(sel["column"]))


def bound_line(results: pd.DataFrame, label: str, experiment: str, scenario: str, detail: dict, consistency: dict) -> dict:
    """One line of a paper's bound table: sqrt(PCRB), efficiency (results rows selected by
    detail plus column = `<prefix>sqrt_pcrb` / `<prefix>efficiency`), ANEES and ANIS with their
    bands and verdicts (selected by consistency)."""
    prefix = detail.pop("prefix", "")
    keys = dict(experiment=experiment, scenario=scenario)
    return {"label": label,
            "sqrt_pcrb": cell_of(results, **keys, **detail, column=f"{prefix}sqrt_pcrb"),
            "efficiency": cell_of(results, **keys, **detail, column=f"{prefix}efficiency"),
            **{stat: with_verdict(cell_of(results, **keys, **consistency, column=stat)) for stat in ("anees", "anis")}}


STUDY_STATS = ("median", "p75", "p95", "rmse", "rmse_3d", "mean", "p90", "max", "availability", "resets", "gated", "time_per_step",
               "calibrated_scale", "calibration_fitted", "range_scale", "range_offset")
BOUND_STATS = ("sqrt_pcrb", "efficiency", "anees", "anis")     # Bayesian filter cells only


def with_verdict(cell: dict) -> dict:
    """An ANEES / ANIS cell (value, band in band_low / band_high) with its verdict (metrics.consistency)."""
    from wsnloc.metrics.consistency import verdict

    if cell["value"] is None or cell["band_low"] is None:
        return dict(cell, verdict=None)
    return dict(cell, verdict=verdict(cell["value"], cell["band_low"], cell["band_high"]))


def _study_cell(results: pd.DataFrame, cell: str, scenario: str) -> dict:
    stats = {stat: cell_of(results, row=cell, scenario=scenario, column=stat) for stat in STUDY_STATS + BOUND_STATS}
    stats.update({stat: with_verdict(stats[stat]) for stat in ("anees", "anis")})
    return stats


def _setting(value) -> str:
    """A parameter value as the config would write it (numbers in the shortest form, 50, 0.05)."""
    if isinstance(value, bool) or value is None:
        return str(value).lower() if value is not None else "none"
    if isinstance(value, (int, float)):
        return format(value, "g")
    return str(value)


def cell_settings(spec: dict, cell: str, label: str) -> list[str]:
    """`name = value` of every parameter the study sets for the cell on one dataset/scenario
    (its own keys and the study's overrides for the dataset or scenario, studies.cell_params)
    where it differs from the registry's default; empty: the registry's defaults."""
    from wsnloc.estimators import registry
    from wsnloc.studies import cell_params, estimator_of

    dataset, scenario = label.split("/", 1)
    defaults = registry.get(estimator_of(spec, cell)).resolve({}, "")
    resolved = cell_params(spec, cell, dataset, scenario, "studies")
    return [f"{name} = {_setting(value)}" for name, value in resolved.items() if value != defaults.get(name)]


def study_section(results: pd.DataFrame, study: str, spec: dict, figures: dict[str, str],
                  headline: list[str] = ("median", "p75", "rmse"), diagnosed: pd.DataFrame | None = None) -> dict:
    """Context of one study's section: the settings of each cell per scenario; per anchor
    subset, cells x scenarios with the `headline` statistics (config report.cell_stats), the
    best cell of each headline column marked (`best`: lowest error, highest availability), and
    every statistic (for the detail); the figures; each run's diagnosis (`diagnosed`: the rows of
    studies.diagnosis_rows, in the cells' and scenarios' order; none without). A study with a 3-D
    cell adds its 3-D RMSE (x, y, z) to the headline; the others are errors in the plane."""
    from wsnloc.studies import EXPERIMENT_PREFIX, FINDINGS_SEPARATOR, estimator_of, runs_on

    sel = results[results["experiment"] == EXPERIMENT_PREFIX + study]
    scenarios, cells = list(spec["scenarios"]), list(spec["estimators"])
    if sel.loc[sel["column"] == "rmse_3d", "value"].notna().any():     # a 3-D cell: its 3-D RMSE beside the 2-D ones
        headline = [*headline, "rmse_3d"]
    tables = []
    for subset in dict.fromkeys(sel["table"]):
        in_subset = sel[sel["table"] == subset]
        rows = [{"label": cell, "cells": [_study_cell(in_subset, cell, sc) for sc in scenarios]} for cell in cells]
        for k in range(len(scenarios)):            # the best cell of each headline column (highest availability)
            for stat in headline:
                values = [r["cells"][k][stat]["value"] for r in rows]
                finite = [v for v in values if v is not None and np.isfinite(v)]
                best = (max(finite) if stat == "availability" else min(finite)) if len(finite) > 1 else None
                for r, v in zip(rows, values):      # no best cell where fewer than two cells have a value
                    r["cells"][k][stat]["best"] = best is not None and v == best
        tables.append({"subset": subset, "scenarios": scenarios, "rows": rows})
    estimators = [{"cell": c, "estimator": estimator_of(spec, c),
                   "settings": [cell_settings(spec, c, sc) if runs_on(spec, c, sc) else None
                                for sc in scenarios]} for c in cells]
    runs = sel.loc[sel["column"] == "rmse", "runs"].dropna()
    rows = [] if diagnosed is None else diagnosed.to_dict("records")
    order = {(c, sc): k for k, (c, sc) in enumerate((c, sc) for c in cells for sc in scenarios)}
    diagnosis = [dict(row, findings=[f for f in str(row["findings"]).split(FINDINGS_SEPARATOR) if f])
                 for row in sorted(rows, key=lambda row: order.get((row["cell"], row["scenario"]), len(order)))]
    return {"id": study, "tables": tables, "estimators": estimators, "scenarios": scenarios,
            "headline": list(headline), "runs": int(runs.min()) if len(runs) else None, "figures": figures,
            "diagnosis": diagnosis}


def static_bounds_section(results: pd.DataFrame, dataset: str, maps: str) -> dict:
    """Context of a dataset's static bounds (analysis.static_bounds): the mean and max CRLB
    along the path per subset, each subset search's named / best / worst subsets with their
    rank and mean CRLB, and the map figure (data URI)."""
    from wsnloc.analysis.static_bounds import EXPERIMENT

    sel = results[(results["experiment"] == EXPERIMENT) & (results["scenario"] == dataset)]
    path = sel[sel["table"] == "CRLB along the path"]
    path_lines = [{"label": row, "mean": cell_of(path, row=row, column="mean"), "max": cell_of(path, row=row, column="max")}
                  for row in dict.fromkeys(path["row"])]
    searches = []
    for table in dict.fromkeys(sel.loc[sel["table"].str.startswith("subset search"), "table"]):
        rows = sel[sel["table"] == table]
        monte_carlo = [c for c in dict.fromkeys(rows["column"]) if c.startswith("RMSE ")]   # opt-in runs
        searches.append({"title": table, "monte_carlo": monte_carlo, "lines": [
            {"label": row, "rank": cell_of(rows, row=row, column="rank"), "mean": cell_of(rows, row=row, column="mean CRLB"),
             "rmse": [cell_of(rows, row=row, column=c) for c in monte_carlo]}
            for row in dict.fromkeys(rows["row"])]})
    return {"path": path_lines, "searches": searches, "maps": maps}


def summary(papers: list[dict]) -> list[dict]:
    """The report's top summary, per paper section: table cells with a paper value and how
    many of those lie inside our 95% interval; claims per verdict."""
    out = []
    for p in papers:
        cells = [cell for table in p["tables"] for row in table["rows"] for cell in row["cells"]
                 if cell["paper"] is not None]
        verdict_counts = {v: sum(c["verdict"] == v for c in p["claims"]) for v in VERDICTS}
        out.append({"id": p["id"], "title": p["title"], "cells": len(cells),
                    "inside": sum(cell["inside"] for cell in cells), "claims": len(p["claims"]),
                    "verdicts": verdict_counts})
    return out


def sensitivity_table(results: pd.DataFrame, experiment: str, claims: list[dict], table: str) -> dict:
    """A paper's claims against the settings of one sensitivity table of results.csv (the
    a-priori sigmas, experiments.sensitivity.TABLE; the UWB ranging levels,
    analysis.nlos_severity.CLAIMS_TABLE): the verdict over all runs, each setting's (the
    baseline first where there is one), and whether the verdict is the same at every setting
    (robust) or flips."""
    from wsnloc.experiments.claims import VERDICT_CODE
    from wsnloc.experiments.sensitivity import BASELINE

    verdict_of = {code: verdict for verdict, code in VERDICT_CODE.items()}
    sel = results[(results["experiment"] == experiment) & (results["table"] == table)]
    if sel.empty:
        return {"settings": [], "rows": []}
    settings = sorted(dict.fromkeys(sel["column"]), key=lambda setting: setting != BASELINE)     # stable
    rows = []
    for c in claims:
        mine = sel[sel["row"] == c["claim"]]
        code = dict(zip(mine["column"], mine["value"]))
        cells = [verdict_of.get(int(code[s])) if s in code and pd.notna(code[s]) else None for s in settings]
        runs = mine["runs"].dropna()
        rows.append({"claim": c["claim"], "all_runs": c["verdict"], "cells": cells,
                     "robust": len(set(cells)) == 1 and cells[0] is not None,
                     "runs": int(runs.min()) if len(runs) else None})
    return {"settings": settings, "rows": rows}


def ranging_section(results: pd.DataFrame, scenarios: list[str], figure: str, notes: list[str]) -> dict:
    """The `Ranging validation` table (metrics.ranging_validation): one line per link class and
    distance bin ('LOS 5-10 m'), per source (the simulated `scenarios` of the data stage, then
    the validation job's real runs and channel-model rows) its median error and p95 |error|
    cells (mean over runs with the 95% interval) and the ranges behind them (whole numbers)."""
    from wsnloc.metrics import ranging_validation as rv

    rows = results[(results["table"] == rv.TABLE)
                   & (results["scenario"].isin(scenarios) | (results["experiment"] == rv.EXPERIMENT))]
    sources = [s for s in scenarios if s in set(rows["scenario"])] \
        + [s for s in dict.fromkeys(rows["scenario"]) if s not in scenarios]
    labels = rows["row"].str.extract(r"^(?P<link>\S+) (?P<low>[0-9.]+)").assign(row=rows["row"])
    order = labels.assign(low=labels["low"].astype(float)).drop_duplicates("row").sort_values(["link", "low"])["row"]
    columns = [*rv.STATS.values(), rv.COUNT_COLUMN]
    lines = []
    for label in order:
        cells = []
        for source in sources:
            for column in columns:
                cells.append({**cell_of(rows, table=rv.TABLE, row=label, column=column, scenario=source),
                              "digits": 0 if column == rv.COUNT_COLUMN else 3})
        lines.append({"label": label, "cells": cells})
    return {"sources": sources, "stats": columns, "lines": lines, "figure": figure, "notes": notes}
