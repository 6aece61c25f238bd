"""How much the UWB link budget depends on the office path loss at 1 m (PL0) of IEEE 802.15.4a
CM3 / CM4, whose published values the project cannot check (docs/simulation.md, "PL0 provenance").

Each variant is the campaign with radio.uwb.channel_models.CM3 / CM4 `path_loss_db_at_1m`
replaced; runs 1..`runs` of each scenario are simulated with the workflow's seeds
(analysis.simulated_runs: run r of every variant shares its seed) and read back by the Newcom++
reader. The runs are simulated here, not read from a build: a sensitivity to a simulator
parameter needs the simulator run under each value, and the campaign's own variant repeats the
workflow's constant / variable runs (same seeds) so that every variant is compared on the same
draws. Per variant and scenario, from the raw tables only (ranges, truth, campaign walls):

- UWB anchors with a valid range per round, from the logs (not the ranges a filter used, which
  paper A's Set-up table counts): the distinct anchors with a valid range (status 0) in each
  ranging round of radio.uwb.ranging_period_ms, mean over the rounds, and the share of rounds
  with fewer than 3 (no 2-D fix from that round alone);
- link share: the share of (round, anchor) pairs with a line in uwb.log (the link closed, valid
  or not), for the LOS and the NLOS pairs (walls crossed at the round's true position);
- the NLOS range error by true-distance bin (metrics.ranging_validation bins): link share of
  the bin, median signed error and p95 |error| (m), pooled over the runs.

Opt-in `claims`: papers A and D decided on the same runs under the campaign's and the
alternative values (their claims as the workflow decides them; the runs' count, not the build's,
sets how many are conclusive).

    python -m wsnloc.analysis.pl0_sensitivity [--runs 10] [--claims] [--out FILE.md]

Cost (measured on the shared 2-core machine): --runs 20 --claims, 160 simulated runs and the
papers' estimators on 80 of them, about 36 s of CPU (75 s wall under load).
Latest output: benchmarks/PL0_SENSITIVITY.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc.analysis.simulated_runs import simulate_tables, with_value
from wsnloc.campaign import Campaign
from wsnloc.metrics import ranging_validation as rv
from wsnloc.metrics.ranging import range_errors, truth_at
from wsnloc.sim import newcom

SCENARIOS = ("constant", "variable")
FEW_ANCHORS = 3          # fewer anchors than this in a round: no 2-D fix from the round alone
# (CM3 PL0, CM4 PL0) in dB per variant; None keeps the campaign's value
VARIANTS = {
    "campaign (MiXiM transcription)": (None, None),
    "CM3 35.4 dB": (35.4, None),
    "CM4 57.9 dB": (None, 57.9),
    "recollection (35.4 / 57.9 dB)": (35.4, 57.9),
}
KEY = ("radio", "uwb", "channel_models")


def variant_campaign(campaign: Campaign, cm3_db: float | None, cm4_db: float | None) -> Campaign:
    """The campaign with CM3 / CM4 PL0 (dB at 1 m) replaced where given."""
    for model, value in (("CM3", cm3_db), ("CM4", cm4_db)):
        if value is not None:
            campaign = with_value(campaign, (*KEY, model, "path_loss_db_at_1m"), value)
    return campaign


def round_links(tables: dict, campaign: Campaign) -> pd.DataFrame:
    """One row per (ranging round, UWB anchor) of a run: true distance (m) and walls at the
    round's true position, `linked` (a uwb.log line, any status) and `valid` (status 0).

    The rounds are the simulator's (sim.newcom.ranging_rounds_ms, from the first truth sample);
    a line belongs to the round whose nominal start is nearest below it by less than half a
    period (the round's jitter and its anchors' spacing stay inside that)."""
    spec = campaign.section("radio", "uwb")
    anchors = campaign.anchors_of("uwb")
    truth, ranges = tables["truth"], tables["ranges"]
    t0, t_end = float(truth["t"].iloc[0]), float(truth["t"].iloc[-1])
    starts_ms = newcom.ranging_rounds_ms(spec, len(anchors), t_end - t0)
    n_rounds, half_ms = len(starts_ms), spec["ranging_period_ms"] / 2.0
    position = truth_at(truth, t0 + starts_ms / 1000.0)
    axy = anchors[["x", "y"]].to_numpy(float)
    slot = {a: j for j, a in enumerate(anchors["anchor_id"])}
    line_ms = (ranges["t"].to_numpy(float) - t0) * 1000.0
    edges = np.concatenate([starts_ms - half_ms, starts_ms[-1:] + half_ms])
    k = np.searchsorted(edges, line_ms, side="right") - 1
    j = ranges["anchor_id"].map(slot).to_numpy()
    inside = (k >= 0) & (k < n_rounds) & pd.notna(j)
    linked = np.zeros((n_rounds, len(axy)), bool)
    valid = np.zeros_like(linked)
    linked[k[inside], j[inside].astype(int)] = True
    ok = inside & (ranges["status"].to_numpy() == 0)
    valid[k[ok], j[ok].astype(int)] = True
    distance = np.hypot(position[:, None, 0] - axy[None, :, 0], position[:, None, 1] - axy[None, :, 1])
    walls = np.column_stack([campaign.walls_between(position, a) for a in axy])
    return pd.DataFrame({"round": np.repeat(np.arange(n_rounds), len(axy)), "true_distance_m": distance.ravel(),
                         "walls": walls.ravel(), "linked": linked.ravel(), "valid": valid.ravel()})


def run_summary(tables: dict, campaign: Campaign) -> dict:
    """UWB anchors with a valid range per round (mean), share of rounds with fewer than FEW_ANCHORS, and link
    share of the LOS / NLOS (round, anchor) pairs of one run (round_links)."""
    links = round_links(tables, campaign)
    heard = links.groupby("round")["valid"].sum()
    nlos = links["walls"] > 0
    return {"anchors_per_epoch": float(heard.mean()), "few_share": float((heard < FEW_ANCHORS).mean()),
            "link_share_los": float(links.loc[~nlos, "linked"].mean()),
            "link_share_nlos": float(links.loc[nlos, "linked"].mean())}


def nlos_bins(runs: dict[str, dict], campaign: Campaign) -> pd.DataFrame:
    """Per NLOS distance bin, pooled over the runs: link share of the bin's (round, anchor)
    pairs, ranges, median signed error and p95 |error| (m) (metrics.ranging_validation)."""
    errors = pd.concat([rv.link_of_walls(range_errors(t["ranges"], t["truth"], campaign)) for t in runs.values()],
                       ignore_index=True)
    stats = rv.per_run(errors.assign(run="pooled"))
    stats = stats[stats["link"] == "NLOS"].set_index("from_m")
    links = pd.concat([round_links(t, campaign) for t in runs.values()], ignore_index=True)
    links = links[links["walls"] > 0]
    edges = np.asarray(rv.DISTANCE_BINS_M)
    slot = np.searchsorted(edges, links["true_distance_m"].to_numpy(), side="right") - 1
    share = links.groupby(edges[slot])["linked"].mean()
    out = pd.DataFrame({"bin": [rv.bin_label(lo, hi) for lo, hi in zip(edges[:-1], edges[1:])],
                        "from_m": edges[:-1]}).set_index("from_m")
    out["link_share"] = share
    out = out.join(stats[["n", "median_m", "p95_abs_m"]])
    return out[out["link_share"].notna()].reset_index(drop=True)


def paper_claims(runs: dict[str, dict[str, dict]], campaign: Campaign, config: dict) -> tuple[dict[str, str], dict]:
    """Verdicts of papers A and D on the variant's runs (runs[scenario][run name] = tables),
    by claim text (paper letter first), decided as the workflow decides them, and paper A's
    cells: mean RMSE over the runs (m) by 'table / row / scenario'."""
    from wsnloc.experiments import paper_a, paper_d

    out = {}
    spec_a, spec_d = config["experiments"]["paper_a"], config["experiments"]["paper_d"]
    per_run_a, per_run_d, motions = {}, {}, {}
    for scenario, tables in runs.items():
        label = f"newcom/{scenario}"
        per_run_a[label] = paper_a.evaluate_runs(tables, campaign, spec_a, label)
        motions[label] = campaign.section("scenarios", scenario)["motion"]
        per_run_d[label] = paper_d.evaluate_runs(tables, campaign, spec_d, label)
    for paper, records in (("A", paper_a.claims(per_run_a, motions, spec_a)), ("D", paper_d.claims(per_run_d))):
        out.update({f"{paper}: {r['claim']}": r["verdict"] for r in records})
    cells = {f"{table} / {row.replace(' | ', ', ')} / {label}": float(rmse) for label, metrics in per_run_a.items()
             for (table, row), rmse in metrics.groupby(["table", "row"], sort=False)["rmse"].mean().items()}
    return out, cells


def analyse(campaign: Campaign, runs: int, seed: int, config: dict | None = None) -> dict:
    """{'summary': per (variant, scenario) mean over runs of run_summary, 'bins': per
    (variant, scenario) nlos_bins, 'claims' and 'cells': per variant paper_claims (with `config`,
    the validated workflow config; only the campaign's and the recollection's variants)}."""
    summary, bins, claims, cells = [], [], {}, {}
    for name, (cm3, cm4) in VARIANTS.items():
        variant = variant_campaign(campaign, cm3, cm4)
        simulated = {s: simulate_tables(variant, s, runs, seed) for s in SCENARIOS}
        for scenario, tables in simulated.items():
            per_run = pd.DataFrame([run_summary(t, variant) for t in tables.values()])
            summary.append({"variant": name, "scenario": scenario, **per_run.mean().to_dict()})
            bins.append(nlos_bins(tables, variant).assign(variant=name, scenario=scenario))
        if config is not None and (cm3 is None) == (cm4 is None):   # the campaign's and the recollection's
            claims[name], cells[name] = paper_claims(simulated, variant, config)
    return {"summary": pd.DataFrame(summary), "bins": pd.concat(bins, ignore_index=True), "claims": claims,
            "cells": pd.DataFrame(cells)}


def markdown(result: dict, runs: int) -> str:
    """The tables of `analyse` as Markdown."""
    s = result["summary"]
    lines = [f"Runs per scenario and variant: {runs} (the workflow's seeds).", "",
             "| variant | scenario | UWB anchors with a valid range per round (logs) | rounds with < 3 | link share LOS | "
             "link share NLOS |",
             "|---|---|---|---|---|---|"]
    lines += [f"| {r.variant} | {r.scenario} | {r.anchors_per_epoch:.2f} | {r.few_share:.1%} | "
              f"{r.link_share_los:.1%} | {r.link_share_nlos:.1%} |" for r in s.itertuples()]
    lines += ["", "NLOS links by true distance (pooled over runs): link share, valid ranges, median error, p95 |error|.", "",
              "| variant | scenario | bin | link share | ranges | median [m] | p95 abs [m] |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {r.variant} | {r.scenario} | {r.bin} | {r.link_share:.1%} | "
              + (f"{int(r.n)} | {r.median_m:.3f} | {r.p95_abs_m:.3f} |" if pd.notna(r.n) else "< 5 | | |")
              for r in result["bins"].itertuples()]
    if result["claims"]:
        names = list(result["claims"])
        lines += ["", "| claim | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        texts = list(dict.fromkeys(c for v in result["claims"].values() for c in v))
        for text in texts:
            verdicts = [result["claims"][n].get(text, "") for n in names]
            flag = "" if len(set(verdicts)) == 1 else " **(differs)**"
            lines.append(f"| {text}{flag} | " + " | ".join(verdicts) + " |")
        cells = result["cells"]
        lines += ["", "Paper A's cells, mean RMSE over the runs [m]:", "",
                  "| cell | " + " | ".join(cells.columns) + " | difference |", "|---|" + "---|" * (len(cells.columns) + 1)]
        lines += [f"| {cell} | " + " | ".join(f"{v:.3f}" for v in values) + f" | {values.iloc[-1] - values.iloc[0]:+.3f} |"
                  for cell, values in cells.iterrows()]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=10, help="runs per scenario and variant (default 10)")
    parser.add_argument("--claims", action="store_true", help="also decide papers A and D on the runs")
    parser.add_argument("--config", default="config/config.yaml")
    parser.add_argument("--out", help="write the Markdown tables here as well")
    args = parser.parse_args(argv)
    from wsnloc.config import read_yaml
    from wsnloc.validation import validate_config

    config = read_yaml(args.config)
    validate_config(config, "config/schema.yaml")
    campaign = Campaign.load(config["datasets"]["newcom"]["campaign"])
    text = markdown(analyse(campaign, args.runs, config["seed"], config if args.claims else None), args.runs)
    print(text)
    if args.out:
        Path(args.out).write_text(f"`python -m wsnloc.analysis.pl0_sensitivity --runs {args.runs}"
                                  f"{' --claims' if args.claims else ''}`\n\n{text}")


if __name__ == "__main__":
    main()
