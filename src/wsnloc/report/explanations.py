""""Why it differs": the look-ups behind the short explanations under each paper's tables of
its large differences from the paper (each paper's sentences: wsnloc.experiments.paper_x.report).
The sentences are written by hand; every number in them is read from the workflow's results
(results.csv rows) or data summaries (data_summary.json), and a sentence whose numbers are
missing (e.g. no NLOS links in the data) is left out.
"""

from __future__ import annotations

import functools
import math

import pandas as pd

from wsnloc.analysis.setup_facts import SETUP_TABLE
from wsnloc.campaign import Campaign
from wsnloc.experiments import claims as claims_of


class Numbers:
    """Look-ups in results.csv rows and per-scenario data summaries; NaN when absent."""

    def __init__(self, results: pd.DataFrame, summaries: dict[str, dict]):
        self.results = results
        self.summaries = summaries

    def value(self, experiment: str, table: str, row: str, column: str, field: str = "value", **keys) -> float:
        """`field` of the first results row with these experiment, table, row, column and keys
        (columns of results.csv); NaN when there is none or it is missing. The rows of each
        key are indexed once (claims.cell_rows)."""
        match = {"experiment": experiment, "table": table, "row": row, "column": column, **keys}
        rows = claims_of.cell_rows(self.results, tuple(match)).get(tuple(match.values()))
        found = claims_of.column_values(self.results, field)[rows[0]] if rows is not None else math.nan
        return float(found) if pd.notna(found) else math.nan

    def fact(self, experiment: str, fact: str, scenario: str) -> float:
        return self.value(experiment, SETUP_TABLE, fact, scenario)

    def ranging(self, scenario: str) -> dict[str, float]:
        """NLOS share of the valid ranges and the NLOS / LOS median errors (m), pooled over runs."""
        pooled = self.summaries.get(scenario, {}).get("range_error_pooled", {})
        los, nlos = pooled.get("LOS", {}), pooled.get("NLOS", {})
        total = (los.get("n") or 0) + (nlos.get("n") or 0)
        return {"nlos_share": (nlos.get("n") or 0) / total if total else math.nan,
                "nlos_bias_m": _number(nlos.get("bias")), "los_median_m": _number(los.get("median")),
                "nlos_p95_m": _number(nlos.get("p95"))}

    def rss_fit(self, scenario: str) -> dict[str, float]:
        """Path-loss fit over all links (mean over runs): exponent n and residual sigma (dB)."""
        runs = self.summaries.get(scenario, {}).get("per_run", [])
        values = {key: [_number(r.get(key)) for r in runs] for key in ("fit_all_n", "fit_all_sigma_dB")}
        return {key: _mean(v) for key, v in values.items()}


def _number(x) -> float:
    return float(x) if x is not None and not (isinstance(x, float) and math.isnan(x)) else math.nan


def _mean(values) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return sum(finite) / len(finite) if finite else math.nan


def finite(*values) -> bool:
    return all(not math.isnan(v) for v in values)


def ranging_severity(n: Numbers, experiment: str, cells: dict[str, str], reference: str) -> list[str]:
    """One sentence: mean RMSE of `cells` (text -> results row of table nlos_severity.TABLE)
    at every level of the UWB ranging severity sweep, then `reference` (a computed clause or "")."""
    from wsnloc.analysis.nlos_severity import TABLE

    sel = n.results[(n.results["experiment"] == experiment) & (n.results["table"] == TABLE)]
    levels = list(dict.fromkeys(sel["column"]))
    values = {(text, level): n.value(experiment, TABLE, row, level) for text, row in cells.items() for level in levels}
    if not levels or not finite(*values.values()):
        return []
    per_level = "; ".join(f"{level}: " + ", ".join(f"{text} {values[text, level]:.2f} m" for text in cells)
                          for level in levels)
    return [(f"Against UWB ranging severity (extra simulated runs of {sel['scenario'].iloc[0]}, RMSE per level): "
             f"{per_level}{reference}.")]


@functools.lru_cache(maxsize=None)
def _campaign(path: str) -> Campaign:
    """Campaign.load, once per file for all papers' sentences."""
    return Campaign.load(path)


def campaign_of(config: dict, label: str) -> Campaign:
    """The campaign of a dataset/scenario label (its scenario details: speed profile, speed)."""
    return _campaign(config["datasets"][label.split("/", 1)[0]]["campaign"])
