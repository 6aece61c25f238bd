"""Paper A's report section: its tables and detail lines (from results.csv), the set-up note
(section.html.j2 beside this file) and the sentences of "Why it differs"."""

from __future__ import annotations

import pandas as pd

from wsnloc.experiments.paper_a import (DETAIL_METRICS, EXPERIMENT as A, MEASUREMENTS_USED, STATIC_TABLE, TABLES,
                                        cell_params, row_label, subset_fact)
from wsnloc.report.explanations import Numbers, campaign_of, finite
from wsnloc.report.sections import cell_of, columns_of, bound_line, grid_table, paper_section

TITLES = {"Table I": "(plain EKF)", "Table II": "(with motion detection)"}


def section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict, labels: list[str],
            spec: dict, numbers: Numbers, config: dict) -> dict:
    """Context of paper A's section on its scenarios `labels`."""
    rows = [row_label(r) for r in spec["rows"]]
    tables = [grid_table(results, experiment=A, table=t, rows=rows, columns=columns_of(results, A, t),
                         metric="rmse_m", title=f"{t}: RMSE [m] {TITLES[t]}", scenario=", ".join(labels))
              for t in TABLES]
    metrics = [m for m in DETAIL_METRICS.values() if (results["metric"] == m).any()]
    details = [{"title": f"{t} detail", "metrics": metrics,
                "lines": [{"label": f"{r} / {c}", "cells": [
                    cell_of(results, experiment=A, table=f"{t} detail", row=r, scenario=sc, column=column,
                          metric=m) for column, m in DETAIL_METRICS.items() if m in metrics]}
                          for r in rows for sc, c in zip(labels, columns_of(results, A, t))]}
               for t in TABLES]
    bounds = [bound_line(results, f"{t}: {r} / {sc}", A, sc, {"table": f"{t} detail", "row": r},
                         {"table": f"consistency: {t}", "row": r}) for t in TABLES for r in rows for sc in labels]
    setup = cell_params(spec, labels[0], TABLES[0], spec["rows"][0])
    return paper_section(A, paper, spec, claims, figures, numbers=numbers, tables=tables, bounds=bounds, details=details, setup=setup,
                         why=why(numbers, config, labels, spec, setup["epoch_s"]))


def why(n: Numbers, config: dict, scenarios: list[str], spec: dict, epoch_s: float) -> list[str]:
    """Static share, anchors heard, UWB NLOS ranging, RSS model, the static-share sweep; the
    first hybrid row's Table II gain is compared with the paper's."""
    hybrid = next((row_label(r) for r in spec["rows"] if r["measurements"] == "hybrid"), None)
    subsets = {kind: [r["anchors"] for r in spec["rows"] if r["measurements"] == kind] for kind in ("toa", "rss")}
    out = []
    for sc in scenarios:
        motion = campaign_of(config, sc).section("scenarios", sc.split("/", 1)[1])["motion"]
        static = n.fact(A, "static share of epochs", sc)
        ours = n.value(A, "Table II", hybrid, motion) - n.value(A, "Table I", hybrid, motion)
        paper = (n.value(A, "Table II", hybrid, motion, "paper_value")
                 - n.value(A, "Table I", hybrid, motion, "paper_value"))
        if finite(static, ours, paper):
            out.append(f"{sc}: motion detection can only help while the cart stands still, {static:.0%} of the epochs "
                       f"here (the paper does not state its share); Table II changes the {hybrid} RMSE by "
                       f"{ours:+.3f} m, the paper's by {paper:+.3f} m.")
        used = {subset: n.fact(A, subset_fact(MEASUREMENTS_USED[kind], subset), sc)
                for kind in ("toa", "rss") for subset in subsets[kind]}
        if used and finite(*used.values()):
            per_subset = ", ".join(f"{used[s]:.1f} {'UWB ranges' if s in subsets['toa'] else 'ZigBee RSS values'} "
                                   f"with {s}" for s in used)
            out.append(f"{sc}: per {epoch_s:g} s epoch the filters use {per_subset} (links that close in the "
                       f"campaign's link budget: UWB 802.15.4a path loss and shadowing against the receiver's sensitivity, "
                       f"ZigBee RSS against the CC2420 sensitivity); the paper: \"only few UWB and few ZigBee anchor "
                       f"nodes\" (paper A, §V).")
        r, fit = n.ranging(sc), n.rss_fit(sc)
        if finite(r["nlos_share"], r["nlos_bias_m"], r["los_median_m"]):
            out.append(f"{sc}: {r['nlos_share']:.0%} of the UWB ranges cross a wall, with a median excess of "
                       f"{r['nlos_bias_m']:.2f} m (LOS median error {r['los_median_m']:.2f} m): the TOA rows are "
                       f"limited by NLOS bias, which the filter's range noise does not model.")
        if finite(fit["fit_all_n"], fit["fit_all_sigma_dB"]):
            out.append(f"{sc}: RSS against distance over all links fits n = {fit['fit_all_n']:.2f} with "
                       f"{fit['fit_all_sigma_dB']:.1f} dB residual spread; wall losses are not in the filter's RSS "
                       f"model, so the RSS rows carry that spread.")
    sweep = n.results[(n.results["experiment"] == A) & (n.results["table"] == STATIC_TABLE)]
    if len(sweep):
        share = sweep[sweep["metric"] == "share"].set_index("column")["value"]
        gain = sweep[sweep["metric"] == "rmse_gain_m"].set_index("column")["value"]
        first, last = share.idxmin(), share.idxmax()
        if first != last and first in gain and last in gain:
            out.append(f"Static-share sweep ({sweep['scenario'].iloc[0]}, longer final rests): the Table II gain goes "
                       f"from {gain[first]:+.3f} m at {share[first]:.0%} static epochs to {gain[last]:+.3f} m at "
                       f"{share[last]:.0%} (figure below).")
    return out
