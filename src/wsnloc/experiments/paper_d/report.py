"""Paper D's report section: Tables 1-3 and details (from results.csv), the cost table, the
set-up note (section.html.j2 beside this file) and the sentences of "Why it differs"."""

from __future__ import annotations

import pandas as pd

from wsnloc.experiments import cells
from wsnloc.experiments.paper_b import EXPERIMENT as B, METHODS
from wsnloc.experiments.paper_d import COST_LABEL, EXPERIMENT as D, LOCALIZER_LABEL, PAPER, SPEEDLESS_ROW, \
    TECHNIQUE_LABEL
from wsnloc.report.explanations import Numbers, finite, ranging_severity
from wsnloc.report.sections import detail_table, paper_section, paper_table


def section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict, labels: list[str],
            spec: dict, numbers: Numbers, config: dict) -> dict:
    """Context of paper D's section on its scenarios `labels`."""
    locs, techs = list(LOCALIZER_LABEL.values()), list(TECHNIQUE_LABEL.values())
    tables, details = [], []
    for scenario in labels:
        for table, title in (("Table 1", "Localization RMSE [m]"),
                             ("Table 2", "Localization followed by velocity tracking, RMSE [m]")):
            tables.append(paper_table(results, experiment=D, table=table, scenario=scenario, rows=locs,
                                      columns=techs, metric="rmse_m", title=f"{table}: {title}"))
            details.append(detail_table(results, experiment=D, table=table, scenario=scenario, rows=locs,
                                        columns=techs, metrics=["median_m", "p95_m", "max_m", "availability"]))
        tables.append(paper_table(results, experiment=D, table="Table 3", scenario=scenario,
                                  rows=["velocity tracker", "Kalman filter"], columns=techs, metric="rmse_m",
                                  title="Table 3: velocity tracking vs Kalman filter on Min-Max fixes, RMSE [m]"))
    setup = cells.params(spec, "velocity", labels[0], PAPER)
    return paper_section(D, paper, spec, claims, figures, numbers=numbers, tables=tables, details=details, cost=cost_table(results),
                         setup=setup, why=why(numbers, labels))


def cost_table(results: pd.DataFrame) -> list[dict]:
    """The Cost table: per tracker (and their ratio) the measured time per step (us), the
    arithmetic operations per step (metrics.op_counts) and the paper's time (us)."""
    sel = results[(results["experiment"] == D) & (results["table"] == "Cost")]

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


def why(n: Numbers, scenarios: list[str]) -> list[str]:
    """UWB against narrowband quality, the KF's speed input, operation counts."""
    out = []
    for sc in scenarios:
        uwb, nb = (n.value(D, "Table 1", "Min-Max", t, scenario=sc) for t in ("UWB", "narrowband"))
        r = n.ranging(sc)
        paper_b_uwb = n.value(B, "RMSE", METHODS["uwb"], sc, "paper_value")
        if finite(uwb, nb, r["nlos_share"], r["nlos_bias_m"], r["nlos_p95_m"]):
            out.append(f"{sc}: Min-Max on UWB {uwb:.2f} m against {nb:.2f} m on narrowband: {r['nlos_share']:.0%} "
                       f"of the UWB ranges are NLOS, median excess {r['nlos_bias_m']:.2f} m (95th percentile "
                       f"{r['nlos_p95_m']:.2f} m). With one source this much better, mixing in the other tends to "
                       f"add error (see the fusion claims)"
                       + (f"; paper B reports Min-Max on UWB of the same database at {paper_b_uwb:.2f} m."
                          if finite(paper_b_uwb) else "."))
    for sc in scenarios:
        kf, vel, without, v_hat, v = (n.value(D, "Table 3", row, "F-mix", scenario=sc, metric=metric) for row, metric in (
            ("Kalman filter", "rmse_m"), ("velocity tracker", "rmse_m"), (SPEEDLESS_ROW, "rmse_m"),
            ("Kalman filter", "speed_input_mps"), ("Kalman filter", "true_speed_mps")))
        if finite(kf, vel, without, v_hat, v):
            out.append(f"{sc}: the Kalman filter is fed the velocity algorithm's speed (seed 004 4.2), the path length "
                       f"of the last raw Min-Max F-mix fixes over its duration (eq. 1): {v_hat:.2f} m/s on average "
                       f"against a true {v:.2f} m/s, as every step's length adds the fixes' noise. Carrying that speed, "
                       f"the KF reaches {kf:.2f} m against the velocity tracker's {vel:.2f} m; without the speed input "
                       f"the same KF gives {without:.2f} m.")
    out += ranging_severity(n, D, {"Min-Max UWB": "minmax/uwb/raw", "narrowband": "minmax/narrowband/raw"}, "")
    ratio = n.value(D, "Cost", "Kalman / velocity", "total per step")
    paper = n.value(D, "Cost", "Kalman / velocity", "total per step", "paper_value")
    if finite(ratio, paper):
        out.append(f"Cost: the Kalman filter needs {ratio:.1f} times the velocity tracker's arithmetic operations per "
                   f"step, the paper measured {paper:.0f} times its time on a StrongARM; the wall-clock ratio of "
                   f"Python code measures interpreter overhead, not arithmetic.")
    return out
