"""Ranging validation: range errors by link class (LOS / NLOS) and true-distance bin.

The same statistics for every source, so that they can be set side by side:
- each simulated scenario (the data stage, per run: mean over runs with its 95% interval);
- the real UWB runs (outdoor cucudasluv cases with RTK truth; their LOS / NLOS class is the
  case's folder, as that campaign has no walls), per case;
- the IEEE 802.15.4a channel models alone (CM3 LOS, CM4 NLOS through one wall) read by the
  campaign's receiver (link budget and detector of sim.newcom) at distances drawn uniformly in
  each bin: what the standard's channel statistics give without the floor's geometry.
Per (class, bin): the median signed error (m), the 95th percentile of |error| (m) and the number
of ranges behind them (all runs; a bin of a few ranges of one link is one link's bias, not a law).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc import results

DISTANCE_BINS_M = (0.0, 2.0, 5.0, 10.0, 20.0, 40.0, 80.0, float("inf"))   # true distance bins (m)
TABLE = "Ranging validation"
EXPERIMENT = "ranging"            # rows of the validation job (real runs, channel model alone)
STATS = {"median_m": "median error", "p95_abs_m": "p95 |error|"}
COUNT_COLUMN = "ranges"           # the ranges behind a (class, bin): all runs' together
MIN_SAMPLES = 5                   # a (run, class, bin) with fewer ranges gives no statistic


def bin_label(low: float, high: float) -> str:
    """'5-10 m', '80+ m'."""
    return f"{low:g}+ m" if not np.isfinite(high) else f"{low:g}-{high:g} m"


def row_label(link: str, low: float, high: float) -> str:
    return f"{link} {bin_label(low, high)}"


def per_run(errors: pd.DataFrame) -> pd.DataFrame:
    """Per (run, link, bin): n, median signed error and p95 |error| (m) of `errors` (columns run,
    link, true_distance_m, error_m); groups with fewer than MIN_SAMPLES ranges are left out."""
    columns = ["run", "link", "from_m", "to_m", "n", *STATS]
    if len(errors) == 0:
        return pd.DataFrame(columns=columns)
    edges = np.asarray(DISTANCE_BINS_M)
    slot = np.searchsorted(edges, errors["true_distance_m"].to_numpy(float), side="right") - 1
    e = errors.assign(slot=slot, abs_error=errors["error_m"].abs())
    e = e[(e["slot"] >= 0) & (e["slot"] < len(edges) - 1)]
    g = e.groupby(["run", "link", "slot"], sort=True)
    out = pd.DataFrame({"n": g.size(), "median_m": g["error_m"].median(),
                        "p95_abs_m": g["abs_error"].quantile(0.95)}).reset_index()
    out = out[out["n"] >= MIN_SAMPLES]
    out["from_m"], out["to_m"] = edges[out["slot"]], edges[out["slot"] + 1]
    return out[columns].reset_index(drop=True)


def rows(errors: pd.DataFrame, experiment: str, scenario: str) -> list[dict]:
    """results rows (table TABLE, row 'LOS 5-10 m', columns STATS, metric range_error_m): mean
    over the runs of each per-run statistic (per_run), with its 95% interval; and COUNT_COLUMN,
    the ranges of those runs (metric count)."""
    out = []
    stats = per_run(errors)
    for (link, low, high), group in stats.groupby(["link", "from_m", "to_m"], sort=True):
        row = row_label(link, low, high)
        for key, column in STATS.items():
            out.append(results.row_over_runs(group[key], experiment=experiment, table=TABLE, row=row, column=column,
                                             scenario=scenario, metric="range_error_m"))
        out.append(results.single_row(int(group["n"].sum()), experiment=experiment, table=TABLE, row=row,
                                      column=COUNT_COLUMN, scenario=scenario, metric="count"))
    return out


def link_of_walls(errors: pd.DataFrame) -> pd.DataFrame:
    """errors with link = 'LOS' where no campaign wall is crossed, else 'NLOS'."""
    return errors.assign(link=np.where(errors["walls"] == 0, "LOS", "NLOS"))


def channel_model_errors(campaign, links_per_bin: int, rng: np.random.Generator,
                         max_distance_m: float = 20.0) -> pd.DataFrame:
    """Range errors (m) of the 802.15.4a channel models alone read by the campaign's UWB receiver:
    per distance bin up to max_distance_m, `links_per_bin` links at distances uniform in the bin,
    CM3 without wall (link LOS) and CM4 through one wall (link NLOS), shadowing drawn
    independently per link; error = excess path of the wall + c (detected delay + timing noise);
    links below the sensitivity or without a tap above the noise-referenced threshold give none.
    Column run = 'model' (one pooled sample)."""
    from wsnloc.sim import link_budget, uwb_channel

    spec = campaign.section("radio", "uwb")
    c = campaign.spec["speed_of_light_mps"]
    noise_mw = 10 ** (link_budget.first_path_threshold_dbm(spec) / 10)
    frames = []
    edges = [e for e in DISTANCE_BINS_M if e < max_distance_m] + [max_distance_m]
    for low, high in zip(edges[:-1], edges[1:]):
        d = rng.uniform(max(low, 0.5), high, links_per_bin)
        for link, name, walls in (("LOS", "CM3", 0), ("NLOS", "CM4", 1)):
            nlos = np.full(len(d), walls > 0)
            power = link_budget.received_power_dbm(spec, d, nlos, rng.standard_normal(len(d)))
            heard = power >= spec["sensitivity_dbm"]
            delay = uwb_channel.detected_delays_ns(
                spec["channel_models"][name], rng, int(heard.sum()), spec["cir_tap_ns"], spec["detector"],
                spec["leading_edge_threshold_db"], 10 ** (power[heard] / 10),
                np.full(int(heard.sum()), 10 ** (-walls * spec["direct_path_wall_loss_db"] / 10)), noise_mw)
            delay = delay + rng.normal(0.0, spec["timing_noise_ns"], len(delay))
            error = walls * spec["excess_path_per_wall_m"] + c * delay * 1e-9
            keep = np.isfinite(error)
            frames.append(pd.DataFrame({"run": "model", "link": link, "true_distance_m": d[heard][keep],
                                        "error_m": error[keep]}))
    return pd.concat(frames, ignore_index=True)


def single_rows(errors: pd.DataFrame, experiment: str, scenario: str) -> list[dict]:
    """results rows of one pooled sample (no runs): per (link, bin) median and p95 |error|, and
    the ranges (COUNT_COLUMN)."""
    stats = per_run(errors.assign(run="pooled"))
    values = {**{key: (column, "range_error_m", float) for key, column in STATS.items()},
              "n": (COUNT_COLUMN, "count", int)}
    return [results.single_row(kind(line[key]), experiment=experiment, table=TABLE,
                               row=row_label(line["link"], line["from_m"], line["to_m"]), column=column,
                               scenario=scenario, metric=metric)
            for _, line in stats.iterrows() for key, (column, metric, kind) in values.items()]


def real_errors(source: str, campaign_file: str) -> pd.DataFrame:
    """Range errors of the real cucudasluv cases (columns run 'los/<case>', link LOS / NLOS from
    the case's folder, true_distance_m 3-D with the campaign's tag height, error_m): the source
    converted by `wsnloc convert cucudasluv` (its ranges alone) into a scratch folder and
    ingested like any run."""
    import tempfile
    from pathlib import Path

    from wsnloc.campaign import Campaign
    from wsnloc.io import generic
    from wsnloc.io.convert import convert_cucudasluv
    from wsnloc.metrics.ranging import range_errors

    campaign = Campaign.load(campaign_file)
    frames = []
    with tempfile.TemporaryDirectory() as scratch:
        for run in convert_cucudasluv(source, scratch, ranges_only=True):
            tables, _ = generic.ingest_run(run.run_dir, campaign)
            case = Path(run.run_dir)
            errors = range_errors(tables["ranges"], tables["truth"], campaign, tables["anchors"])
            frames.append(errors.assign(run=f"{case.parent.name}/{case.name}", link=case.parent.name.upper()))
    return pd.concat(frames, ignore_index=True)


def curves(table: pd.DataFrame) -> dict[str, dict[str, pd.DataFrame]]:
    """Figure input (report.figures.ranging_validation) from TABLE rows: {column: {'<scenario>
    <link>': frame x (geometric bin centre, m; the last, open bin at 1.5x its start), value,
    ci95_low, ci95_high}}."""
    rows = table[table["table"] == TABLE]
    parts = rows["row"].str.extract(r"^(?P<link>\S+) (?P<low>[0-9.]+)(?:-(?P<high>[0-9.]+))?")
    low, high = parts["low"].astype(float), parts["high"].astype(float)
    x = np.where(high.notna(), np.sqrt(np.maximum(low, 0.5) * high.fillna(1.0)), 1.5 * low)
    rows = rows.assign(x=x, link=parts["link"]).sort_values("x")
    out: dict[str, dict[str, pd.DataFrame]] = {}
    for column in STATS.values():
        chosen = rows[rows["column"] == column]
        out[column] = {f"{scenario} {link}": group[["x", "value", "ci95_low", "ci95_high"]].reset_index(drop=True)
                       for (scenario, link), group in chosen.groupby(["scenario", "link"], sort=False)}
    return out
