"""Ingest raw run directories of any supported format into the canonical Parquet tables.

Layout written: <out>/<run>/<table>.parquet for the tables of wsnloc.io.tables.RAW_TABLES,
plus <out>/inventory.json (per run and file: SHA-256, lines, quarantined lines, and
where the format has them: RF-only records, rows reordered by time, unknown anchors).
A run over the quarantine limits (wsnloc.io.limits) stops the scenario.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io import cricket, generic, newcom, tables
from wsnloc.io.limits import QuarantineLimits, check_quarantine_limits, over_limits

PARSERS: dict[str, Callable[[Path, Campaign], tuple[dict[str, pd.DataFrame], dict]]] = {
    "newcom": newcom.ingest_run,
    "cricket": cricket.ingest_run,
    "generic": generic.ingest_run,
}


def parser_for(fmt: str):
    try:
        return PARSERS[fmt]
    except KeyError:
        raise IngestError(f"unknown raw format {fmt!r} (known: {', '.join(sorted(PARSERS))})") from None


INVENTORY_NOTES = {"rf_only": "RF-only record(s) (no range)", "reordered": "row(s) out of time order (sorted)"}


def file_notes(info: dict) -> str:
    """What one file's inventory entry notes beside its counts ('12 row(s) out of time order
    (sorted)', ...), '' when nothing."""
    return ", ".join(f"{info[key]} {label}" for key, label in INVENTORY_NOTES.items() if info.get(key))


def ingest_one(fmt: str, run_dir: str | Path, campaign: Campaign | None, out_dir: str | Path) -> dict:
    """Parse one run directory and write its tables to out_dir; returns its inventory.

    `campaign` may be None for the generic format only (it needs no campaign).
    """
    if campaign is None and fmt != "generic":
        raise IngestError(f"the {fmt} format needs a campaign file (anchors, path, radio parameters)")
    result, inventory = parser_for(fmt)(Path(run_dir), campaign)
    result = {**{name: tables.empty(name) for name in tables.RAW_TABLES}, **result}   # tables a format lacks: empty
    out_dir = Path(out_dir)
    for name, frame in result.items():
        tables.write(name, frame, out_dir / f"{name}.parquet",
                     {"source_dir": str(run_dir), "format": fmt, "campaign": campaign.name if campaign else "none"})
    return inventory


def ingest_scenario(fmt: str, run_dirs: dict[str, str], campaign: Campaign | None, out_dir: str | Path,
                    limits: QuarantineLimits, keep_dir: str | Path) -> dict:
    """Ingest every run of a scenario; stops at the first run over the quarantine limits.

    That run's quarantine table is copied to <keep_dir>/<run>.quarantine.csv first, since a
    failed job's outputs (out_dir) are deleted by Snakemake; the error names that copy.
    """
    out_dir = Path(out_dir)
    inventory = {}
    for run, run_dir in run_dirs.items():
        inventory[run] = ingest_one(fmt, run_dir, campaign, out_dir / run)
        if over_limits(inventory[run], limits) is not None:
            _stop(run_dir, inventory[run], out_dir / run / "quarantine.parquet", limits,
                  Path(keep_dir) / f"{run}.quarantine.csv")
    (out_dir / "inventory.json").write_text(json.dumps(inventory, indent=1, sort_keys=True))
    return inventory


def _stop(run_dir: str | Path, inventory: dict, quarantine_path: Path, limits: QuarantineLimits, kept: Path) -> None:
    """Copy the quarantine table of a run over the limits (over_limits is not None) to `kept`,
    then raise check_quarantine_limits' IngestError naming that copy. The table is read
    back only here: a run within the limits needs nothing but its inventory."""
    quarantine = tables.read(quarantine_path)
    kept.parent.mkdir(parents=True, exist_ok=True)
    quarantine.to_csv(kept, index=False)
    check_quarantine_limits(run_dir, inventory, quarantine, limits, kept)
