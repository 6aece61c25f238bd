"""Paper B's report section: its tables and details (from results.csv), the set-up note and
the differences of protocol (section.html.j2 beside this file) and the sentences of "Why it
differs"."""

from __future__ import annotations

import pandas as pd

from wsnloc.experiments import cells
from wsnloc.experiments.paper_b import EXPERIMENT as B, METHODS, PAPER, SNR_TABLE
from wsnloc.report.explanations import Numbers, finite, ranging_severity
from wsnloc.sim.imu import ACCEL_BIAS, GYRO_BIAS
from wsnloc.report.sections import cell_of, columns_of, grid_table, paper_section


def section(results: pd.DataFrame, claims: dict, figures: dict[str, str], paper: dict, labels: list[str],
            spec: dict, numbers: Numbers, config: dict) -> dict:
    """Context of paper B's section: RMSE and max error per method and scenario `labels`."""
    methods = list(METHODS.values())
    tables = []
    for table, metric, title in (("RMSE", "rmse_m", "RMSE [m]"), ("Max error", "max_m", "Max error [m]")):
        sel = results[(results["experiment"] == B) & (results["table"] == table)]
        grid = {"title": f"{title} (paper: simulation column beside b_simulation, real-data column beside the "
                         f"campaign scenarios)", "scenario": ", ".join(labels), "columns": labels, "rows": []}
        for method in methods:
            grid["rows"].append({"label": method, "cells": [
                cell_of(sel, row=method, scenario=sc, metric=metric) for sc in labels]})
        tables.append(grid)
    snr_columns = columns_of(results, B, SNR_TABLE)
    if snr_columns:
        tables.append(grid_table(results, experiment=B, table=SNR_TABLE, rows=[METHODS["imu"]], columns=snr_columns,
                                 metric="rmse_m", title=f"{SNR_TABLE}, RMSE [m] (noise added to the 5 Hz output)",
                                 scenario=", ".join(dict.fromkeys(results[results["table"] == SNR_TABLE]["scenario"]))))
    details = [{"title": f"Detail, {sc}", "metrics": ["median_m", "p95_m"],
                "lines": [{"label": m, "cells": [cell_of(results, experiment=B, table="Detail", scenario=sc, row=m,
                                                       column=stat, metric=f"{stat}_m") for stat in ("median", "p95")]}
                          for m in methods]} for sc in labels]
    simulated = list(spec.get("simulation_scenarios", []))
    measured = [label for label in labels if label not in simulated]
    setup = cells.params(spec, "sskf", (measured or labels)[0], PAPER)
    simulation_setup = cells.params(spec, "sskf", simulated[0], PAPER) if simulated else setup
    return paper_section(B, paper, spec, claims, figures, numbers=numbers, tables=tables, details=details, setup=setup,
                         simulation_setup=simulation_setup, why=why(numbers, measured, simulated),
                         paper_terms=lambda table, row, column, cell: paper_terms(numbers, row["label"], column, cell))


def paper_terms(n: Numbers, row: str, column: str, cell: dict) -> list[tuple[str, float | None]]:
    """Paper B's own terms of a cell's gap (explanations.cell_whys): below the paper on Min-Max
    UWB, the era of the paper's ranging hardware from the UWB ranging severity sweep (our
    Min-Max RMSE with 2009-era IEEE 802.15.4a ranging minus that with the spec's DW1000-class
    ranging, on the sweep's scenario: an error the paper's data carry and ours lack, counted
    negative); on the SNR curve's cell, the SNR at which our curve meets the paper's value
    (log-linear between the two SNRs around it) and the noise amplitude ratio 10^(-dSNR/20)
    it implies (a statement: the reading of the paper's SNR)."""
    from wsnloc.analysis.nlos_severity import TABLE

    scenario = cell.get("scenario") or column
    if row == METHODS["uwb"] and cell["delta"] < 0:
        sweep = n.results[(n.results["experiment"] == B) & (n.results["table"] == TABLE)
                          & (n.results["row"] == "uwb") & (n.results["scenario"] == scenario)]
        if len(sweep) >= 2:
            (spec_level, spec_rmse), (era_level, era_rmse) = (sweep[["column", "value"]].iloc[i] for i in (0, -1))
            return [(f"the paper's era of UWB ranging ({era_level}: our Min-Max {era_rmse:.3f} m against "
                     f"{spec_rmse:.3f} m with {spec_level}): {spec_rmse:.3f} - {era_rmse:.3f} = "
                     f"{spec_rmse - era_rmse:+.3f} m", spec_rmse - era_rmse)]
    if row == METHODS["imu"] and column.endswith(" dB"):
        curve = n.results[(n.results["experiment"] == B) & (n.results["table"] == SNR_TABLE)]
        snr = curve["column"].str.removesuffix(" dB").astype(float).to_numpy()
        rmse = curve["value"].to_numpy(float)
        paper, at = cell["paper"], float(column.removesuffix(" dB"))
        # dead reckoning error falls with the SNR: the neighbours of the paper's value on our curve
        pairs = [(i, i + 1) for i in range(len(snr) - 1)
                 if min(rmse[i], rmse[i + 1]) <= paper <= max(rmse[i], rmse[i + 1])]
        if pairs:
            i, j = pairs[0]
            meet = snr[i] + (snr[j] - snr[i]) * (rmse[i] - paper) / (rmse[i] - rmse[j])
            return [(f"our SNR curve meets the paper's {paper:.3f} m at {snr[i]:g} + {snr[j] - snr[i]:g} x "
                     f"({rmse[i]:.3f} - {paper:.3f}) / ({rmse[i]:.3f} - {rmse[j]:.3f}) = {meet:.1f} dB: the paper's "
                     f"{at:g} dB carries accelerometer noise 10^(-{meet - at:.1f}/20) = "
                     f"{10 ** (-(meet - at) / 20):.2f} times the amplitude of ours at {at:g} dB (the paper's SNR "
                     f"referred to another signal power than ours)", None)]
    return []


def why(n: Numbers, scenarios: list[str], simulated: list[str]) -> list[str]:
    """Dead reckoning against SNR, UWB NLOS ranging, rests."""
    out = []
    imu, uwb = METHODS["imu"], METHODS["uwb"]
    for sc in simulated:
        ours, paper = n.value(B, "RMSE", imu, sc), n.value(B, "RMSE", imu, sc, "paper_value")
        at50, at60, at70 = (n.value(B, SNR_TABLE, imu, f"{snr} dB") for snr in (50, 60, 70))
        if finite(ours, paper, at50, at60, at70):
            out.append(f"{sc}: dead reckoning {ours:.2f} m against the paper's {paper:.2f} m. With the noise added to "
                       f"the 5 Hz accelerometer output, our curve (figure below) gives {at50:.2f} m at 50 dB, "
                       f"{at60:.2f} m at 60 dB and {at70:.2f} m at 70 dB SNR: the reading of the paper's SNR decides "
                       f"this column.")
    for sc in scenarios:
        ours, paper = n.value(B, "RMSE", uwb, sc), n.value(B, "RMSE", uwb, sc, "paper_value")
        r = n.ranging(sc)
        if finite(ours, paper, r["nlos_share"], r["nlos_bias_m"]):
            out.append(f"{sc}: Min-Max on UWB {ours:.2f} m against the paper's {paper:.2f} m: {r['nlos_share']:.0%} "
                       f"of our UWB ranges are NLOS with a median excess of only {r['nlos_bias_m']:.2f} m.")
        static = n.fact(B, "static share of epochs", sc)
        if finite(static):
            out.append(f"{sc}: the cart stands still {static:.0%} of the time, as the paper's \"continuously "
                       f"moving\" cart: there is no rest to measure the sensor biases in.")
        dr, dr_paper = n.value(B, "RMSE", imu, sc), n.value(B, "RMSE", imu, sc, "paper_value")
        accel, gyro, duration = n.imu_bias_sigma(sc, ACCEL_BIAS), n.imu_bias_sigma(sc, GYRO_BIAS), n.duration_s(sc)
        if finite(dr, dr_paper, accel, gyro, duration) and dr > dr_paper and accel > 0:
            out.append(f"{sc}: dead reckoning {dr:.2f} m against the paper's {dr_paper:.2f} m: without a bias "
                       f"calibration the accelerometer's turn-on bias ({accel:g} m/s^2 per axis, 1 sigma, campaign) "
                       f"integrates to b T^2 / 2 ({0.5 * accel * duration**2:.0f} m over the {duration:.0f} s run) "
                       f"and the gyro bias ({gyro:g} deg/s) turns the heading by {gyro * duration:.0f} deg over "
                       f"it ({dr / dr_paper:.0f}x the paper's error); the paper's "
                       f"{dr_paper:.2f} m implies biases removed beforehand (seed 001 III.A models a bias from static "
                       f"recordings), which the text does not report for this run.")
    real = [v for v in (n.value(B, "RMSE", uwb, sc, "paper_value") for sc in scenarios) if finite(v)]
    out += ranging_severity(n, B, {"Min-Max on UWB": "uwb"},
                            f"; the paper's real data: {real[0]:.2f} m" if real else "")
    return out
