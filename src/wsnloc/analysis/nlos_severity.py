"""A paper's claim verdicts against the severity of NLOS UWB ranging.

Severity knob: `radio.uwb.excess_path_per_wall_m` of the campaign (m added to a UWB range
per wall the direct path crosses; the campaign's value models the slower propagation
through a wall, larger values the late first-path detections of narrower-band, 2009-era
IEEE 802.15.4a prototypes). For each value, runs 1..`runs` of `scenario` are simulated
(analysis.simulated_runs, paired across values) and evaluated by the caller's estimators;
the per-run metrics of each value then decide the paper's claims like the main runs
(experiments.sensitivity.results_rows, one column per value).
"""

from __future__ import annotations

from typing import Callable

import pandas as pd

from wsnloc.analysis.simulated_runs import simulate_tables, with_value
from wsnloc.campaign import Campaign

KNOB = ("radio", "uwb", "excess_path_per_wall_m")


def setting_label(excess_m: float, runs: int) -> str:
    return f"NLOS excess {excess_m:g} m/wall ({runs} simulated runs)"


def sweep(campaign: Campaign, scenario: str, excess_m, runs: int, seed: int,
          evaluate: Callable[[Campaign, dict[str, dict]], pd.DataFrame], dataset: str = "newcom") -> pd.DataFrame:
    """Per-run metrics of every severity value, with a `setting` column (setting_label).

    evaluate(campaign, tables by run name) -> per-run metrics of those runs (column `run`).
    """
    frames = []
    for value in excess_m:
        severe = with_value(campaign, KNOB, float(value))
        tables = simulate_tables(severe, scenario, runs, seed, dataset)
        frames.append(evaluate(severe, tables).assign(setting=setting_label(value, runs)))
    return pd.concat(frames, ignore_index=True)


def claim_rows(experiment: str, spec: dict | None, campaign_file: str, seed: int,
               evaluate: Callable[[Campaign, dict], pd.DataFrame], claims) -> list[dict]:
    """results.csv rows of a paper's claims against NLOS ranging severity (config `nlos_sweep`:
    scenario, excess_per_wall_m, runs; none when runs is 0): `evaluate(campaign, tables)` gives
    the per-run metrics of extra simulated runs at each severity, `claims` decides on them."""
    from wsnloc.experiments import sensitivity

    spec = spec or {"runs": 0}
    if not spec["runs"]:
        return []
    dataset, scenario = spec["scenario"].split("/", 1)
    severity = sweep(Campaign.load(campaign_file), scenario, spec["excess_per_wall_m"], spec["runs"], seed, evaluate,
                     dataset)
    return sensitivity.results_rows(experiment, {spec["scenario"]: severity}, claims)
