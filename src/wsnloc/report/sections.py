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


def _cell(results: pd.DataFrame, **keys) -> dict:
    """The first row of `results` where every key column equals its value, as a table cell;
    rows and columns are indexed once per frame (claims.cell_rows, claims.column_values)."""
    rows = claims_of.cell_rows(results, tuple(keys)).get(tuple(keys.values()))
    if rows is None:
        return {"value": None, "low": None, "high": None, "band_low": None, "band_high": None, "runs": None,
                "paper": None, "delta": None, "inside": False, "basis": "mean"}
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
            "basis": basis}


def _present(results: pd.DataFrame, column: str, row: int):
    """results[column] at position `row`, None where missing."""
    value = claims_of.column_values(results, column)[row]
    return value if pd.notna(value) else None


def paper_table(results: pd.DataFrame, *, experiment: str, table: str, scenario: str, rows: list[str],
                columns: list[str], metric: str, title: str) -> dict:
    return {
        "title": title, "scenario": scenario, "columns": columns,
        "rows": [{"label": r, "cells": [_cell(results, experiment=experiment, table=table, scenario=scenario,
                                              row=r, column=c, metric=metric) for c in columns]} for r in rows],
    }


def detail_table(results: pd.DataFrame, *, experiment: str, table: str, scenario: str, rows: list[str],
                 columns: list[str], metrics: list[str]) -> dict:
    """Median, percentiles, max (and availability) per cell: one line per (row, column)."""
    lines = []
    for r in rows:
        for c in columns:
            cells = [_cell(results, experiment=experiment, table=table, scenario=scenario, row=r, column=c, metric=m)
                     for m in metrics]
            lines.append({"label": f"{r} / {c}", "cells": cells})
    return {"title": f"{table} detail, {scenario}", "metrics": metrics, "lines": lines}


def paper_d_section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict,
                    scenarios: list[str], settings: dict) -> dict:
    """Context of paper D's section."""
    from wsnloc.experiments.paper_d import LOCALIZER_LABEL, TECHNIQUE_LABEL

    locs, techs = list(LOCALIZER_LABEL.values()), list(TECHNIQUE_LABEL.values())
    tables, details = [], []
    for scenario in scenarios:
        for table, title in (("Table 1", "Localization RMSE [m]"),
                             ("Table 2", "Localization followed by velocity tracking, RMSE [m]")):
            tables.append(paper_table(results, experiment="D", table=table, scenario=scenario, rows=locs,
                                      columns=techs, metric="rmse_m", title=f"{table}: {title}"))
            details.append(detail_table(results, experiment="D", table=table, scenario=scenario, rows=locs,
                                        columns=techs, metrics=["median_m", "p95_m", "max_m", "availability"]))
        tables.append(paper_table(results, experiment="D", table="Table 3", scenario=scenario,
                                  rows=["velocity tracker", "Kalman filter"], columns=techs, metric="rmse_m",
                                  title="Table 3: velocity tracking vs Kalman filter on Min-Max fixes, RMSE [m]"))
    cost = cost_table(results)
    return {
        "id": "D", "title": paper["title"], "citation": paper["citation"],
        "published": bool(paper.get("tables_published", True)),
        "tables": tables, "details": details, "claims": claims["claims"], "cost": cost,
        "figures": figures, "settings": settings,
    }




def cost_table(results: pd.DataFrame) -> list[dict]:
    """Paper D's Cost table: per tracker (and their ratio) the measured time per step (us),
    the arithmetic operations per step (metrics.op_counts) and the paper's time (us)."""
    from wsnloc.experiments.paper_d import COST_LABEL

    sel = results[(results["experiment"] == "D") & (results["table"] == "Cost")]

    def value(row, column, metric):
        match = sel[(sel["row"] == row) & (sel["column"] == column) & (sel["metric"] == metric)]
        return (match["value"].iloc[0], match["paper_value"].iloc[0]) if len(match) else (None, None)

    lines = []
    for label in (*COST_LABEL.values(), "Kalman / velocity"):
        ratio = label == "Kalman / velocity"
        time_metric = "ratio" if ratio else "us_per_step"
        time, paper = value(label, "time per step", time_metric)
        ops = value(label, "total per step", "ratio" if ratio else "ops_per_step")[0]
        kinds = {kind: value(label, f"{kind} per step", "ops_per_step")[0] for kind in ("mul", "add", "div", "sqrt")}
        lines.append({"label": label, "ratio": ratio, "time": time, "operations": ops, "kinds": kinds,
                      "paper": paper})
    return lines


def paper_b_section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict,
                    scenarios: list[str], settings: dict) -> dict:
    """Context of paper B's section: RMSE and max error per method and scenario."""
    from wsnloc.experiments.paper_b import METHODS, SNR_TABLE

    methods = list(METHODS.values())
    tables = []
    for table, metric, title in (("RMSE", "rmse_m", "RMSE [m]"), ("Max error", "max_m", "Max error [m]")):
        sel = results[(results["experiment"] == "B") & (results["table"] == table)]
        grid = {"title": f"{title} (paper: simulation column beside b_simulation, real-data column beside the "
                         f"campaign scenarios)", "scenario": ", ".join(scenarios), "columns": scenarios, "rows": []}
        for method in methods:
            grid["rows"].append({"label": method, "cells": [
                _cell(sel, row=method, scenario=sc, metric=metric) for sc in scenarios]})
        tables.append(grid)
    snr_columns = _columns(results, "B", SNR_TABLE)
    if snr_columns:
        tables.append(grid_table(results, experiment="B", table=SNR_TABLE, rows=[METHODS["imu"]], columns=snr_columns,
                                 metric="rmse_m", title=f"{SNR_TABLE}, RMSE [m] (noise added to the 5 Hz output)",
                                 scenario=", ".join(dict.fromkeys(results[results["table"] == SNR_TABLE]["scenario"]))))
    details = [{"title": f"Detail, {sc}", "metrics": ["median_m", "p95_m"],
                "lines": [{"label": m, "cells": [_cell(results, experiment="B", table="Detail", scenario=sc, row=m,
                                                       column=stat, metric=f"{stat}_m") for stat in ("median", "p95")]}
                          for m in methods]} for sc in scenarios]
    return {"id": "B", "title": paper["title"], "citation": paper["citation"], "published": True,
            "tables": tables, "details": details, "claims": claims["claims"], "cost": [],
            "figures": figures, "settings": settings}


def grid_table(results: pd.DataFrame, *, experiment: str, table: str, rows: list[str], columns: list[str],
               metric: str, title: str, scenario: str = "") -> dict:
    """A paper table whose cells are found by (table, row, column) across scenarios."""
    sel = results[(results["experiment"] == experiment) & (results["table"] == table)]
    return {"title": title, "scenario": scenario, "columns": columns,
            "rows": [{"label": r, "cells": [_cell(sel, row=r, column=c, metric=metric) for c in columns]} for r in rows]}


def _columns(results: pd.DataFrame, experiment: str, table: str) -> list[str]:
    sel = results[(results["experiment"] == experiment) & (results["table"] == table)]
    return list(dict.fromkeys(sel["column"]))


def bound_line(results: pd.DataFrame, label: str, experiment: str, scenario: str, detail: dict, consistency: dict) -> dict:
    """One line of a paper's bound table: sqrt(PCRB), efficiency (results rows selected by
    detail plus column = `<prefix>sqrt_pcrb` / `<prefix>efficiency`), ANEES and ANIS with their
    bands and verdicts (selected by consistency)."""
    prefix = detail.pop("prefix", "")
    keys = dict(experiment=experiment, scenario=scenario)
    return {"label": label,
            "sqrt_pcrb": _cell(results, **keys, **detail, column=f"{prefix}sqrt_pcrb"),
            "efficiency": _cell(results, **keys, **detail, column=f"{prefix}efficiency"),
            **{stat: with_verdict(_cell(results, **keys, **consistency, column=stat)) for stat in ("anees", "anis")}}


def paper_a_section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict,
                    scenarios: list[str], settings: dict) -> dict:
    from wsnloc.experiments.paper_a import row_label

    rows = [row_label(r) for r in settings["rows"]]
    tables = [grid_table(results, experiment="A", table=t, rows=rows, columns=_columns(results, "A", t),
                         metric="rmse_m", title=f"{t}: RMSE [m] {title}", scenario=", ".join(scenarios))
              for t, title in (("Table I", "(plain EKF)"), ("Table II", "(with motion detection)"))]
    from wsnloc.experiments.paper_a import DETAIL_METRICS

    metrics = [m for m in DETAIL_METRICS.values() if (results["metric"] == m).any()]
    details = [{"title": f"{t} detail", "metrics": metrics,
                "lines": [{"label": f"{r} / {c}", "cells": [
                    _cell(results, experiment="A", table=f"{t} detail", row=r, scenario=sc, column=column,
                          metric=m) for column, m in DETAIL_METRICS.items() if m in metrics]}
                          for r in rows for sc, c in zip(scenarios, _columns(results, "A", t))]}
               for t in ("Table I", "Table II")]
    bounds = [bound_line(results, f"{t}: {r} / {sc}", "A", sc, {"table": f"{t} detail", "row": r},
                         {"table": f"consistency: {t}", "row": r}) for t in ("Table I", "Table II") for r in rows
              for sc in scenarios]
    return {"id": "A", "title": paper["title"], "citation": paper["citation"], "published": True, "tables": tables,
            "bounds": bounds, "details": details, "claims": claims["claims"], "cost": [], "figures": figures, "settings": settings}


def paper_c_section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict,
                    scenarios: list[str], settings: dict) -> dict:
    from wsnloc.experiments.paper_c import MODELS

    tables = [
        grid_table(results, experiment="C", table="Table I", rows=list(MODELS), columns=_columns(results, "C", "Table I"),
                   metric="rmse_m", title=f"Table I: RMSE [m], beacons {settings['table_1_subset']}",
                   scenario=", ".join(scenarios)),
        grid_table(results, experiment="C", table="Table II", rows=list(settings["table_2_subsets"]),
                   columns=list(MODELS), metric="rmse_m", title="Table II: RMSE [m] by beacon set",
                   scenario=settings["table_2_scenario"]),
    ]
    detail_columns = _columns(results, "C", "Table I detail")
    details = [{"title": "Table I detail (median, p95, max per speed)", "metrics": detail_columns,
                "lines": [{"label": m, "cells": [_cell(results, experiment="C", table="Table I detail", row=m, column=c)
                                                 for c in detail_columns]} for m in MODELS]}]
    speeds = [c.removesuffix(" efficiency") for c in detail_columns if c.endswith(" efficiency")]   # scenario order
    bounds = [bound_line(results, f"{m} / {sc}", "C", sc, {"table": "Table I detail", "row": m, "prefix": f"{speed} "},
                         {"table": f"consistency: {settings['table_1_subset']}", "row": m})
              for m in MODELS for sc, speed in zip(scenarios, speeds)]
    bounds += [bound_line(results, f"Table II: {subset}, {m} / {settings['table_2_scenario']}", "C",
                          settings["table_2_scenario"], {"table": "Table II detail", "row": subset, "prefix": f"{m} "},
                          {"table": f"consistency: {subset}", "row": m})
               for subset in settings["table_2_subsets"] for m in MODELS]
    return {"id": "C", "title": paper["title"], "citation": paper["citation"], "published": True, "tables": tables,
            "bounds": bounds, "details": details, "claims": claims["claims"], "cost": [], "figures": figures, "settings": settings}


STUDY_STATS = ("median", "p75", "p95", "rmse", "mean", "p90", "max", "availability", "resets", "gated", "time_per_step",
               "calibrated_scale", "calibration_fitted", "range_scale", "range_offset")
BOUND_STATS = ("sqrt_pcrb", "efficiency", "anees", "anis")     # Bayesian filter cells only


def with_verdict(cell: dict) -> dict:
    """An ANEES / ANIS cell (value, band in band_low / band_high) with its verdict (metrics.consistency)."""
    from wsnloc.metrics.consistency import verdict

    if cell["value"] is None or cell["band_low"] is None:
        return dict(cell, verdict=None)
    return dict(cell, verdict=verdict(cell["value"], cell["band_low"], cell["band_high"]))


def _study_cell(results: pd.DataFrame, cell: str, scenario: str) -> dict:
    stats = {stat: _cell(results, row=cell, scenario=scenario, column=stat) for stat in STUDY_STATS + BOUND_STATS}
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
                  headline: list[str] = ("median", "p75", "rmse")) -> dict:
    """Context of one study's section: the settings of each cell per scenario; per anchor
    subset, cells x scenarios with the `headline` statistics (config report.cell_stats), the
    best cell of each headline column marked (`best`: lowest error, highest availability), and
    every statistic (for the detail); the figures."""
    from wsnloc.studies import EXPERIMENT_PREFIX, estimator_of

    sel = results[results["experiment"] == EXPERIMENT_PREFIX + study]
    scenarios, cells = list(spec["scenarios"]), list(spec["estimators"])
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
                   "settings": [cell_settings(spec, c, sc) for sc in scenarios]} for c in cells]
    runs = sel.loc[sel["column"] == "rmse", "runs"].dropna()
    return {"id": study, "tables": tables, "estimators": estimators, "scenarios": scenarios,
            "headline": list(headline), "runs": int(runs.min()) if len(runs) else None, "figures": figures}


def static_bounds_section(results: pd.DataFrame, dataset: str, maps: str) -> dict:
    """Context of a dataset's static bounds (analysis.static_bounds): the mean and max CRLB
    along the path per subset, each subset search's named / best / worst subsets with their
    rank and mean CRLB, and the map figure (data URI)."""
    from wsnloc.analysis.static_bounds import EXPERIMENT

    sel = results[(results["experiment"] == EXPERIMENT) & (results["scenario"] == dataset)]
    path = sel[sel["table"] == "CRLB along the path"]
    path_lines = [{"label": row, "mean": _cell(path, row=row, column="mean"), "max": _cell(path, row=row, column="max")}
                  for row in dict.fromkeys(path["row"])]
    searches = []
    for table in dict.fromkeys(sel.loc[sel["table"].str.startswith("subset search"), "table"]):
        rows = sel[sel["table"] == table]
        monte_carlo = [c for c in dict.fromkeys(rows["column"]) if c.startswith("RMSE ")]   # opt-in runs
        searches.append({"title": table, "monte_carlo": monte_carlo, "lines": [
            {"label": row, "rank": _cell(rows, row=row, column="rank"), "mean": _cell(rows, row=row, column="mean CRLB"),
             "rmse": [_cell(rows, row=row, column=c) for c in monte_carlo]}
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


def sensitivity_table(results: pd.DataFrame, experiment: str, claims: list[dict]) -> dict:
    """A paper's claims against its sensitivity settings (experiments.sensitivity): the verdict
    over all runs, the baseline and every setting on the sampled runs, and whether the sampled
    verdict is the same at every setting (robust) or flips."""
    from wsnloc.experiments.claims import VERDICT_CODE
    from wsnloc.experiments.sensitivity import BASELINE, TABLE

    verdict_of = {code: verdict for verdict, code in VERDICT_CODE.items()}
    sel = results[(results["experiment"] == experiment) & (results["table"] == TABLE)]
    if sel.empty:
        return {"settings": [], "rows": []}
    settings = [BASELINE] + [c for c in dict.fromkeys(sel["column"]) if c != BASELINE]
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
    cells (mean over runs with the 95% interval)."""
    from wsnloc.metrics import ranging_validation as rv

    rows = results[(results["table"] == rv.TABLE)
                   & (results["scenario"].isin(scenarios) | (results["experiment"] == rv.EXPERIMENT))]
    sources = [s for s in scenarios if s in set(rows["scenario"])] \
        + [s for s in dict.fromkeys(rows["scenario"]) if s not in scenarios]
    labels = rows["row"].str.extract(r"^(?P<link>\S+) (?P<low>[0-9.]+)").assign(row=rows["row"])
    order = labels.assign(low=labels["low"].astype(float)).drop_duplicates("row").sort_values(["link", "low"])["row"]
    lines = []
    for label in order:
        cells = []
        for source in sources:
            for column in rv.STATS.values():
                cells.append(_cell(rows, table=rv.TABLE, row=label, column=column, scenario=source))
        lines.append({"label": label, "cells": cells})
    return {"sources": sources, "stats": list(rv.STATS.values()), "lines": lines, "figure": figure, "notes": notes}
