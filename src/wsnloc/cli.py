"""Command line for use outside Snakemake: simulate, ingest, convert, estimators, estimate, validate-config.

`estimators` lists the registry; `estimate` runs one estimator on one run.

Exit codes: 0 success, 2 bad input (unreadable log, invalid config) with a one-line
message naming the file/line or key.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.validation import validate_config
from wsnloc.errors import WsnlocError
from wsnloc.estimators.parameters import parse_assignment
from wsnloc.io.ingest import PARSERS, file_notes, ingest_one
from wsnloc.io import tables
from wsnloc.io.limits import (DEFAULT_PER_FILE, DEFAULT_PER_RUN, QuarantineLimits, check_quarantine_limits,
                              quarantine_share)
from wsnloc.workflow import run_name


def _default_campaign(fmt: str) -> str:
    return f"config/campaigns/{fmt}.yaml"


def cmd_simulate(args) -> int:
    from wsnloc.sim import SIMULATORS
    from wsnloc.sim.seeding import run_seed_sequence

    campaign = Campaign.load(args.campaign)
    if campaign.format not in SIMULATORS:
        raise WsnlocError(f"{args.campaign}: no simulator for format {campaign.format!r} "
                          f"(available: {', '.join(SIMULATORS)})")
    simulate_run = SIMULATORS[campaign.format]
    total = args.first_run + args.runs - 1
    for index in range(args.first_run, total + 1):
        seeds = run_seed_sequence(args.seed, args.dataset, args.scenario, index)
        run = run_name(index, total)
        out = simulate_run(campaign, args.scenario, seeds, Path(args.out) / run, detector=args.detector,
                           imu_noise=args.imu_noise, meta={"run": run, "base_seed": args.seed, "dataset": args.dataset})
        print(f"wrote {out}")
    return 0


def _ingest_campaign(args) -> Campaign | None:
    """The --campaign file, else the format's default, as the run's scenario sees it (the
    `scenario` its meta.yaml names, as the simulator writes it: a 3-D scenario's heights,
    Campaign.for_scenario); a generic run needs none (its meta.yaml may give the tag height:
    io.generic.run_campaign)."""
    if args.format == "generic" and not args.campaign:
        from wsnloc.io.generic import run_campaign

        return run_campaign(args.run_dir)
    campaign = Campaign.load(args.campaign or _default_campaign(args.format))
    meta = Path(args.run_dir) / "meta.yaml"
    scenario = (read_yaml(meta) or {}).get("scenario") if meta.is_file() else None
    return campaign.for_scenario(str(scenario)) if scenario else campaign


def cmd_ingest(args) -> int:
    inventory = ingest_one(args.format, args.run_dir, _ingest_campaign(args), args.out_dir)
    print(f"{'file':<14} {'records':>9} {'quarantined':>12}  notes")
    for name, info in inventory.items():
        notes = file_notes(info)
        print(f"{name:<14} {info['data_lines']:>9} {info['quarantined']:>12}  {notes}")
        for anchor, count in info.get("unknown_anchors", {}).items():
            print(f"{'':<14} {count:>9} row(s) of anchor {anchor!r}, missing from the anchors table")
    quarantine_path = Path(args.out_dir) / "quarantine.parquet"
    quarantine = tables.read(quarantine_path)
    if len(quarantine):
        print("quarantine by reason:")
        from wsnloc.metrics.data_quality import quarantine_by_reason

        for file, reason, count in quarantine_by_reason(quarantine):
            print(f"  {count:>6}  {file}: {reason}")
    print(f"quarantined share: {quarantine_share(inventory):.2%}; tables written to {args.out_dir}")
    check_quarantine_limits(args.run_dir, inventory, quarantine, _quarantine_limits(args), quarantine_path)
    return 0


QUARANTINE_OPTIONS = ("--max-quarantine-share", "--max-quarantine-share-per-file")     # per run, per file


def _add_quarantine_options(command: argparse.ArgumentParser) -> None:
    """The quarantine limits of a command that ingests a run (io.limits; the workflow's config
    keys ingest.max_quarantine_share / _per_file, same defaults)."""
    command.add_argument(QUARANTINE_OPTIONS[0], type=float, default=DEFAULT_PER_RUN,
                         help="exit 2 when a larger share of the run is quarantined (default: %(default)s)")
    command.add_argument(QUARANTINE_OPTIONS[1], type=float, default=DEFAULT_PER_FILE,
                         help="exit 2 when a larger share of one file is quarantined (default: %(default)s)")


def _quarantine_limits(args) -> QuarantineLimits:
    return QuarantineLimits(args.max_quarantine_share, args.max_quarantine_share_per_file,
                            tuple(f"option {option}" for option in QUARANTINE_OPTIONS))


def cmd_convert(args) -> int:
    from wsnloc.io.convert import CONVERTERS, QUARANTINE_FILE
    from wsnloc.io.tdoa_from_ranges import convert_tdoa

    for run in {**CONVERTERS, "tdoa": convert_tdoa}[args.dataset](args.src, args.out):
        bad = f"; {len(run.quarantine)} source line(s) quarantined, see {run.run_dir / QUARANTINE_FILE}" \
            if run.quarantine else ""
        print(f"wrote {run.run_dir}{bad}")
    return 0


def cmd_estimators(args) -> int:
    from wsnloc.estimators import registry

    described = [e.describe() for e in registry.ESTIMATORS.values()]
    if args.json:
        print(json.dumps(described, indent=1))
        return 0
    for e in described:
        default = " (default of `wsnloc estimate`)" if e["name"] == registry.DEFAULT_ESTIMATOR else ""
        tdoa = " [TDOA]" if e["tdoa"] else ""
        print(f"{e['name']}{default}{tdoa}: {e['summary']}")
        for p in e["parameters"]:
            unit = f" [{p['unit']}]" if p["unit"] else ""
            choices = f" ({' | '.join(p['choices'])})" if p.get("choices") else ""
            print(f"    {p['name']} = {p['default']!r}{unit}{choices}: {p['doc']}")
    return 0


def cmd_estimate(args) -> int:
    from wsnloc.estimate import estimate_run

    overrides = dict(parse_assignment(text) for text in args.set or [])
    campaign = _ingest_campaign(args)
    metrics = estimate_run(args.format, Path(args.run_dir), campaign, Path(args.out), args.estimator, overrides,
                           Path(args.calibration) if args.calibration else None, _quarantine_limits(args))
    notes, diagnosis = metrics.pop("notes"), metrics.pop("diagnosis")
    for note in notes:
        print(f"note: {note}")
    print(f"{args.estimator}: {metrics.pop('n_estimates')} estimates written to {Path(args.out) / 'estimates.parquet'}")
    if metrics:  # n: the estimates scored against truth (inside its time span)
        print("  " + ", ".join(f"n scored {v:.0f}" if k == "n" else f"{k} {v:.3f}" for k, v in metrics.items()))
    else:
        print("  not scored: the run has no truth")
    print(diagnosis)
    return 0


def cmd_validate(args) -> int:
    config = read_yaml(args.config)
    validate_config(config if config is not None else {}, args.schema)
    print(f"{args.config}: valid")
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="wsnloc", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    sim = sub.add_parser("simulate", help="simulate runs of a campaign scenario into raw logs")
    sim.add_argument("--campaign", default=_default_campaign("newcom"), help="campaign file (default: %(default)s)")
    sim.add_argument("--scenario", required=True, help="scenario name in the campaign file")
    sim.add_argument("--runs", type=int, default=1, help="number of runs (default: %(default)s)")
    sim.add_argument("--first-run", type=int, default=1, help="index of the first run (default: %(default)s)")
    sim.add_argument("--seed", type=int, default=20130101, help="base seed (default: %(default)s)")
    sim.add_argument("--dataset", default="newcom", help="dataset name entering the seed (default: %(default)s)")
    sim.add_argument("--detector", choices=["first_path", "strongest_path"], help="UWB detector override")
    sim.add_argument("--imu-noise", choices=["mems", "snr"], help="IMU noise model override")
    sim.add_argument("--out", required=True, help="output directory; runs go to OUT/run-NN")
    sim.set_defaults(func=cmd_simulate)

    ing = sub.add_parser("ingest", help="parse one raw run directory into Parquet tables",
                         description="Parse one raw run directory into Parquet tables; exit code 2 when a "
                                     "file or the run is over the quarantine limits (the tables are written).")
    ing.add_argument("--format", required=True, choices=sorted(PARSERS))
    ing.add_argument("--campaign", help="campaign file (default: config/campaigns/<format>.yaml; "
                                        "the generic format needs none)")
    _add_quarantine_options(ing)
    ing.add_argument("run_dir")
    ing.add_argument("out_dir")
    ing.set_defaults(func=cmd_ingest)

    conv = sub.add_parser("convert", help="convert a public dataset into the generic format")
    conv.add_argument("dataset", choices=["cucudasluv", "philotuxo", "tdoa"],
                      help="cucudasluv: outdoor UWB (OUT/<los|nlos>/<case>); philotuxo: BLE RSSI (OUT/tracks/<track>); "
                           "tdoa: the generic run(s) below SRC with range differences to a reference anchor made from their "
                           "ranges (wsnloc.io.tdoa_from_ranges)")
    conv.add_argument("src", help="the dataset's folder (e.g. realdata/cucudasluv-uwb, realdata/philotuxo-ble-rssi)")
    conv.add_argument("out", help="output folder; runs go to OUT/<scenario>/<run>")
    conv.set_defaults(func=cmd_convert)

    est = sub.add_parser("estimators", help="list the estimator registry with each parameter, default and unit")
    est.add_argument("--json", action="store_true", help="machine-readable: a list of {name, summary, parameters}")
    est.set_defaults(func=cmd_estimators)

    run = sub.add_parser("estimate", help="run one estimator on one raw run directory")
    run.add_argument("--format", required=True, choices=sorted(PARSERS))
    run.add_argument("run_dir", help="a raw run directory (e.g. data/raw/newcom/constant/run-01)")
    run.add_argument("--out", required=True, help="output folder: estimates.parquet, metrics.json, tables/")
    run.add_argument("--estimator", default="tracker",
                     help="registry name (default: %(default)s, the recommended tracker; see `wsnloc estimators`)")
    run.add_argument("--set", action="append", metavar="KEY=VALUE",
                     help="parameter override (repeatable). The measurement kind follows the run: a run with "
                          "two-way ranges is tracked on them (they carry more information) even when it has "
                          "tdoa.csv too (a note says so; --set measurements=tdoa reads the range differences); "
                          "a run with range differences only is tracked on them")
    run.add_argument("--campaign", help="campaign file (default: config/campaigns/<format>.yaml; optional for "
                                        "generic runs: no walls, 3-D ranges only where anchors have z)")
    run.add_argument("--calibration", help="a donor run directory with truth, same format and site: the RSS "
                                           "model (estimators reading RSS) and, on a run with ranges, the range "
                                           "scale and per-anchor offsets are fitted on it (range_calibration="
                                           "other_run unless --set gives another)")
    _add_quarantine_options(run)
    run.set_defaults(func=cmd_estimate)

    val = sub.add_parser("validate-config", help="validate a workflow configuration file")
    val.add_argument("config", nargs="?", default="config/config.yaml")
    val.add_argument("--schema", default="config/schema.yaml")
    val.set_defaults(func=cmd_validate)
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.func(args)
    except (WsnlocError, ValueError) as exc:
        print(f"wsnloc {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
