"""A paper's claim verdicts against the severity of UWB ranging errors.

Levels (config `nlos_sweep.levels`, name -> parameter set): each level is the campaign with
its radio.uwb values replaced, first by one of the campaign's hardware classes
(`hardware_class`: radio.uwb.hardware_classes, e.g. the 2009-era IEEE 802.15.4a class), then
by the level's own radio.uwb values (e.g. `excess_path_per_wall_m`: m added to a UWB range
per wall the direct path crosses); `{}` is the campaign's own radio.uwb. For each level, runs
1..`runs` of `scenario` are simulated (analysis.simulated_runs, paired across levels) and
evaluated by the caller's estimators; the per-run metrics of each level then decide the
paper's claims like the main runs (experiments.sensitivity.results_rows, one column per
level, labelled by setting_label).
"""

from __future__ import annotations

from typing import Callable

import pandas as pd

from wsnloc import results
from wsnloc.analysis.simulated_runs import simulate_tables, with_value
from wsnloc.campaign import Campaign
from wsnloc.errors import ConfigError

TABLE = "UWB ranging severity"   # results.csv: mean RMSE of every cell at every level
CLAIMS_TABLE = "Sensitivity to UWB ranging"     # results.csv: every claim's verdict at every level

# radio.uwb values a level may set (config/schema.yaml $defs.nlos_level), with their label text
LEVEL_TEXT = {
    "excess_path_per_wall_m": "NLOS excess {:g} m/wall",
    "timing_noise_ns": "timing noise {:g} ns",
    "cir_tap_ns": "tap {:g} ns",
    "leading_edge_threshold_db": "leading edge {:g} dB",
    "twr_clock_ppm": "clock {:g} ppm",
    "twr_reply_time_us": "reply {:g} us",
}


def level_campaign(campaign: Campaign, level: dict, where: str) -> Campaign:
    """The campaign with radio.uwb replaced by the level's hardware class, then by the level's
    own values; `where` (the level's config key) names the key in errors."""
    values = {}
    if "hardware_class" in level:
        classes = campaign.section("radio", "uwb").get("hardware_classes", {})
        if level["hardware_class"] not in classes:
            raise ConfigError(f"config key '{where}.hardware_class': no hardware class {level['hardware_class']!r} "
                              f"in {campaign.source} radio.uwb.hardware_classes (have: {', '.join(classes) or 'none'})")
        values.update(classes[level["hardware_class"]])
    values.update({key: level[key] for key in LEVEL_TEXT if key in level})
    for key, value in values.items():
        try:
            campaign = with_value(campaign, ("radio", "uwb", key), value)
        except KeyError as exc:
            raise ConfigError(f"config key '{where}': {exc.args[0]}") from exc
    return campaign


def setting_label(campaign: Campaign, level: dict, runs: int) -> str:
    """Column label of a level: the hardware it simulates (radio.uwb.hardware_label of the
    level's campaign), its own radio.uwb values, and the number of simulated runs."""
    parts = [campaign.section("radio", "uwb").get("hardware_label", "campaign UWB")]
    parts += [text.format(level[key]) for key, text in LEVEL_TEXT.items() if key in level]
    return f"{', '.join(parts)} ({runs} simulated run{'s' if runs != 1 else ''})"


def sweep(campaign: Campaign, scenario: str, levels: dict[str, dict], runs: int, seed: int,
          evaluate: Callable[[Campaign, dict[str, dict]], pd.DataFrame], dataset: str = "newcom",
          where: str = "nlos_sweep.levels", simulated: dict[str, dict] | None = None) -> pd.DataFrame:
    """Per-run metrics of every level, with a `setting` column (setting_label).

    evaluate(campaign, tables by run name) -> per-run metrics of those runs (column `run`).
    simulated: the tables of runs 1..`runs` of the scenario as the workflow simulated and
    ingested them (same campaign, same seeds); a level that changes nothing ({}) reads them
    instead of simulating the same runs again.
    """
    frames = []
    for name, level in levels.items():
        severe = level_campaign(campaign, level, f"{where}.{name}")
        reuse = not level and simulated is not None and len(simulated) == runs
        tables = simulated if reuse else simulate_tables(severe, scenario, runs, seed, dataset)
        frames.append(evaluate(severe, tables).assign(setting=setting_label(severe, level, runs)))
    return pd.concat(frames, ignore_index=True)


def cell_of(metrics: pd.DataFrame) -> pd.Series:
    """Name of each per-run metrics row's cell: its non-numeric columns besides `run` and
    `setting`, joined by "/" (paper B: "uwb"; paper D: "minmax/uwb/raw")."""
    keys = [c for c in metrics.select_dtypes(exclude="number").columns if c not in ("run", "setting")]
    return metrics[keys].astype(str).agg("/".join, axis=1)


def rmse_rows(experiment: str, scenario: str, severity: pd.DataFrame) -> list[dict]:
    """results.csv rows (table TABLE, row = cell_of, column = level label, metric rmse_m):
    mean over the simulated runs of each cell's per-run RMSE (m), with its 95% interval."""
    cells = severity.assign(cell=cell_of(severity))
    return [results.row_over_runs(group["rmse"], experiment=experiment, table=TABLE, row=cell, column=setting,
                                  scenario=scenario, metric="rmse_m")
            for (setting, cell), group in cells.groupby(["setting", "cell"], sort=False)]


def claim_rows(experiment: str, spec: dict | None, campaign_file: str, seed: int,
               evaluate: Callable[[Campaign, dict], pd.DataFrame], claims, simulated_dirs=()) -> list[dict]:
    """results.csv rows of a paper's claims against UWB ranging severity (table CLAIMS_TABLE; config
    `experiments.paper_<experiment>.nlos_sweep`: scenario, levels, runs; none when runs is 0),
    and of every cell's RMSE per level (rmse_rows): `evaluate(campaign, tables)` gives the
    per-run metrics of extra simulated runs at each level, `claims` decides on them.
    simulated_dirs: the workflow's table folders of the (simulated) sweep scenario, whose
    first runs a level without changes reuses (sweep)."""
    from wsnloc.experiments import sensitivity
    from wsnloc.metrics.data_quality import load_runs

    spec = spec or {"runs": 0}
    if not spec["runs"]:
        return []
    dataset, scenario = spec["scenario"].split("/", 1)
    simulated = load_runs(simulated_dirs, first=spec["runs"]) if simulated_dirs else None
    severity = sweep(Campaign.load(campaign_file), scenario, spec["levels"], spec["runs"], seed, evaluate, dataset,
                     f"experiments.paper_{experiment.lower()}.nlos_sweep.levels", simulated)
    return sensitivity.results_rows(experiment, {spec["scenario"]: severity}, claims, CLAIMS_TABLE) \
        + rmse_rows(experiment, spec["scenario"], severity)
