"""Paper C's report section: its tables, bound lines and details (from results.csv), the
set-up note (section.html.j2 beside this file) and the sentences of "Why it differs"."""

from __future__ import annotations

import math

import pandas as pd

from wsnloc.experiments.paper_c import EXPERIMENT as C, MODELS, cell_params, speed_label
from wsnloc.report.explanations import Numbers, campaign_of, finite
from wsnloc.report.sections import cell_of, columns_of, bound_line, grid_table, paper_section


def section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict, labels: list[str],
            spec: dict, numbers: Numbers, config: dict) -> dict:
    """Context of paper C's section on its scenarios `labels`."""
    table_1, table_2, scenario_2 = spec["table_1_subset"], list(spec["table_2_subsets"]), spec["table_2_scenario"]
    tables = [
        grid_table(results, experiment=C, table="Table I", rows=list(MODELS), columns=columns_of(results, C, "Table I"),
                   metric="rmse_m", title=f"Table I: RMSE [m], beacons {table_1}", scenario=", ".join(labels)),
        grid_table(results, experiment=C, table="Table II", rows=table_2, columns=list(MODELS), metric="rmse_m",
                   title="Table II: RMSE [m] by beacon set", scenario=scenario_2),
    ]
    detail_columns = columns_of(results, C, "Table I detail")
    details = [{"title": "Table I detail (median, p95, max per speed)", "metrics": detail_columns,
                "lines": [{"label": m, "cells": [cell_of(results, experiment=C, table="Table I detail", row=m, column=c)
                                                 for c in detail_columns]} for m in MODELS]}]
    speeds = [c.removesuffix(" efficiency") for c in detail_columns if c.endswith(" efficiency")]   # scenario order
    bounds = [bound_line(results, f"{m} / {sc}", C, sc, {"table": "Table I detail", "row": m, "prefix": f"{speed} "},
                         {"table": f"consistency: {table_1}", "row": m})
              for m in MODELS for sc, speed in zip(labels, speeds)]
    bounds += [bound_line(results, f"Table II: {subset}, {m} / {scenario_2}", C, scenario_2,
                          {"table": "Table II detail", "row": subset, "prefix": f"{m} "},
                          {"table": f"consistency: {subset}", "row": m})
               for subset in table_2 for m in MODELS]
    setup = {model: cell_params(spec, labels[0], model, table_1) for model in MODELS}
    campaign = campaign_of(config, labels[0]).spec
    tilt_deg, gravity = campaign.get("imu", {}).get("mount_tilt_sigma_deg", 0.0), campaign["gravity_mps2"]
    return paper_section(C, paper, spec, claims, figures, numbers=numbers, tables=tables, bounds=bounds, details=details, setup=setup,
                         why=why(numbers, config, labels, setup["P"]["epoch_s"]),
                         paper_terms=lambda table, row, column, cell: model_part(
                             numbers, table["table"], row["label"], column, setup["P"]["epoch_s"],
                             setup["PV"]["accel_sigma_mps2"], tilt_deg, gravity))


def model_part(n: Numbers, table: str, row: str, column: str, period_s: float, pv_accel_sigma: float,
               tilt_deg: float, gravity_mps2: float) -> list[tuple[str, float]]:
    """The PV or PVA cell's own part of its gap (explanations.cell_whys): its excess over the P
    model in the same column (Table I: rows are models; Table II: columns are), ours against the
    paper's, (ours_M - ours_P) - (paper_M - paper_P) in m; the rest of the gap is the P cell's.
    Mechanism shown: an acceleration error a left in the prediction over the period T adds
    a T^2 / 2, so the paper's excess dp needs a = 2 dp / T^2 (m/s^2), set against the PV model's
    white acceleration sigma or, for PVA, the tilt leakage g sin(tilt) of our assumed IMU."""
    model, key = (row, {"row": "P", "column": column}) if row in MODELS else (column, {"row": row, "column": "P"})
    if model == "P" or model not in MODELS:
        return []
    values = [n.value(C, table, r, c, field) for r, c in ((row, column), (key["row"], key["column"]))
              for field in ("value", "paper_value")]
    ours_m, paper_m, ours_p, paper_p = values
    if not finite(*values):
        return []
    do, dp = ours_m - ours_p, paper_m - paper_p
    text = (f"{model}'s own part: {model} - P is {dp:+.3f} m in the paper against {do:+.3f} m here, "
            f"{do:+.3f} - ({dp:+.3f}) = {do - dp:+.3f} m")
    if dp > 0:
        a = 2.0 * dp / period_s**2
        if model == "PVA":
            leak = gravity_mps2 * math.sin(math.radians(tilt_deg))
            text += (f"; an acceleration error a left in the prediction over T = {period_s:g} s adds a T^2 / 2, so the "
                     f"paper's {dp:.3f} m needs a = 2 x {dp:.3f} / {period_s:g}^2 = {a:.2f} m/s^2 that its bias states "
                     f"did not absorb, {a / leak:.1f} times the tilt leakage g sin({tilt_deg:g} deg) = "
                     f"{leak:.3f} m/s^2 of our assumed IMU (absorbed here)" if leak > 0 else "")
        else:
            text += (f"; a motion the model does not follow adds a T^2 / 2 over T = {period_s:g} s, so the paper's "
                     f"{dp:.3f} m needs a = 2 x {dp:.3f} / {period_s:g}^2 = {a:.2f} m/s^2 of unmodelled acceleration, "
                     f"{a / pv_accel_sigma:.1f} times our PV model's white-acceleration sigma {pv_accel_sigma:g} m/s^2")
    return [(text, do - dp)]


def why(n: Numbers, config: dict, scenarios: list[str], epoch_s: float) -> list[str]:
    """Assumed IMU for PVA, beacons per epoch, ranging accuracy."""
    out = ["PVA takes the acceleration of an assumed 5 Hz IMU (a Cricket listener has no accelerometer) as the "
           "authors describe theirs: tilted on the cart, so gravity leaks through a per-run mount tilt and the floor's "
           "slope (in the 5 Hz band), with no rest to calibrate it and the gyro heading started from the first fixes; "
           "see the sensitivity table for how the P / PV / PVA ordering depends on the a-priori noise settings."]
    for sc in scenarios:
        speed = speed_label(campaign_of(config, sc), sc.split("/", 1)[1])
        beacons = n.fact(C, "beacons ranged per epoch", sc)
        r = n.ranging(sc)
        ours, paper = n.value(C, "Table I", "P", speed), n.value(C, "Table I", "P", speed, "paper_value")
        if finite(beacons, r["los_median_m"], ours, paper):
            # mechanism: a position error set by the ranging scales with the range error (the PCRB is linear in it)
            out.append(f"{sc}: {beacons:.1f} beacons ranged per {epoch_s:g} s epoch, median range error "
                       f"{r['los_median_m']:.3f} m; P RMSE {ours:.3f} m against the paper's {paper:.3f} m. The "
                       f"position error is ranging-limited and scales with the range error: the paper's value needs "
                       f"ranges about {paper / ours:.1f} times less accurate than ours (median error about "
                       f"{r['los_median_m'] * paper / ours:.3f} m), e.g. from the hand-measured beacon positions "
                       f"the paper mentions.")
    return out
