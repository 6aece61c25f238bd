"""Ingest raw run directories of any supported format into the canonical Parquet tables.

Layout written: <out>/<run>/<table>.parquet for the tables of wsnloc.io.tables.RAW_TABLES,
plus <out>/inventory.json (per run and file: SHA-256, lines, quarantined lines).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io import cricket, generic, newcom, tables

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


def quarantine_share(inventory: dict) -> float:
    """Quarantined records / all records of a run (0 when the run has no records)."""
    records = sum(f["data_lines"] for f in inventory.values())
    bad = sum(f["quarantined"] for f in inventory.values())
    return bad / records if records else 0.0


def ingest_one(fmt: str, run_dir: str | Path, campaign: Campaign, out_dir: str | Path) -> dict:
    """Parse one run directory and write its tables to out_dir; returns its inventory."""
    result, inventory = parser_for(fmt)(Path(run_dir), campaign)
    out_dir = Path(out_dir)
    for name, frame in result.items():
        tables.write(name, frame, out_dir / f"{name}.parquet",
                     {"source_dir": str(run_dir), "format": fmt, "campaign": campaign.name})
    return inventory


def ingest_scenario(fmt: str, run_dirs: dict[str, str], campaign: Campaign, out_dir: str | Path,
                    max_quarantine_share: float) -> dict:
    """Ingest every run of a scenario. Fails loudly if a run's quarantined share exceeds the limit."""
    out_dir = Path(out_dir)
    inventory = {}
    for run, run_dir in run_dirs.items():
        inventory[run] = ingest_one(fmt, run_dir, campaign, out_dir / run)
        share = quarantine_share(inventory[run])
        if share > max_quarantine_share:
            worst = max(inventory[run].items(), key=lambda kv: kv[1]["quarantined"])[0]
            raise IngestError(
                f"{run_dir}: {share:.1%} of the lines are quarantined (most in {worst}), more than "
                f"config key 'ingest.max_quarantine_share' = {max_quarantine_share:.1%} allows; "
                f"see {out_dir / run / 'quarantine.parquet'}")
    (out_dir / "inventory.json").write_text(json.dumps(inventory, indent=1, sort_keys=True))
    return inventory
