"""Quarantine limits: a run whose data is mostly unusable stops the build instead of
reporting numbers from it.

Two shares, each quarantined records / records (data lines, usable or not):
  per file:  of each raw file or table alone, so that a damaged uwb.log is not diluted by
             the run's many 500 Hz IMU lines (config key ingest.max_quarantine_share_per_file,
             option --max-quarantine-share-per-file of `wsnloc ingest` / `estimate`);
  per run:   of all the run's files together (config key ingest.max_quarantine_share, option
             --max-quarantine-share).
The stop message names the file, its dominant reasons with counts and the values that
occur most in those reasons (e.g. an anchor id missing from the anchors), and where the
quarantine table was kept.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from wsnloc.errors import IngestError
from wsnloc.metrics.data_quality import reason_category

DEFAULT_PER_RUN = 0.2          # the defaults of config/schema.yaml (a test keeps them equal)
DEFAULT_PER_FILE = 0.2
CONFIG_KEYS = ("config key 'ingest.max_quarantine_share'", "config key 'ingest.max_quarantine_share_per_file'")
_QUOTED = re.compile(r"'([^']*)'")


@dataclass(frozen=True)
class QuarantineLimits:
    """Largest quarantined shares (0..1) allowed per run and per file, and what sets each (per
    run, per file), named in the stop message: the workflow's config keys, or a command's options."""

    per_run: float = DEFAULT_PER_RUN
    per_file: float = DEFAULT_PER_FILE
    set_by: tuple[str, str] = CONFIG_KEYS


def quarantine_share(inventory: dict) -> float:
    """Quarantined records / all records of a run (0 when the run has no records)."""
    records = sum(f["data_lines"] for f in inventory.values())
    bad = sum(f["quarantined"] for f in inventory.values())
    return bad / records if records else 0.0


def file_shares(inventory: dict) -> dict[str, float]:
    """Quarantined share of each file that has records."""
    return {name: f["quarantined"] / f["data_lines"] for name, f in inventory.items() if f["data_lines"]}


def over_limits(inventory: dict, limits: QuarantineLimits) -> str | None:
    """What is over the quarantine limits, from the inventory alone: the first file whose
    share is above limits.per_file, "" when only the run's share is above limits.per_run,
    None when the run is within both (check_quarantine_limits raises exactly when not None)."""
    over_file = next((name for name, share in file_shares(inventory).items() if share > limits.per_file), None)
    if over_file is not None:
        return over_file
    return "" if quarantine_share(inventory) > limits.per_run else None


def within_limits(inventory: dict, limits: QuarantineLimits) -> bool:
    """Whether check_quarantine_limits passes (over_limits is None)."""
    return over_limits(inventory, limits) is None


def describe(quarantine: pd.DataFrame, file: str, top: int = 3) -> str:
    """The dominant reasons (with counts, grouped as in the report: values become '…' and
    numbers N) and the most frequent quoted values among the quarantined lines of `file`."""
    reasons = quarantine.loc[quarantine["file"] == file, "reason"].tolist()
    kinds = Counter(reason_category(reason) for reason in reasons).most_common(top)
    values = Counter(value for reason in reasons for value in _QUOTED.findall(reason)).most_common(top)
    text = "dominant reasons: " + "; ".join(f"{count} x {kind}" for kind, count in kinds)
    if values:
        text += "; most frequent values: " + ", ".join(f"{value!r} ({count})" for value, count in values)
    return text


def check_quarantine_limits(run_dir: str | Path, inventory: dict, quarantine: pd.DataFrame, limits: QuarantineLimits,
          kept_at: str | Path) -> None:
    """Raise IngestError when a file's or the run's quarantined share exceeds its limit.

    `kept_at`: where the quarantine table of the run can be read after the failure.
    """
    run_dir = Path(run_dir)
    over = over_limits(inventory, limits)
    if over:
        raise IngestError(
            f"{run_dir / over}: {file_shares(inventory)[over]:.1%} of its {inventory[over]['data_lines']} records are "
            f"quarantined, more than {limits.set_by[1]} = {limits.per_file:.1%} "
            f"allows; {describe(quarantine, over)}; quarantine table: {kept_at}")
    if over == "":
        worst = max(inventory, key=lambda name: inventory[name]["quarantined"])
        raise IngestError(
            f"{run_dir}: {quarantine_share(inventory):.1%} of the run's records are quarantined (most in {worst}), "
            f"more than {limits.set_by[0]} = {limits.per_run:.1%} allows; {worst}: "
            f"{describe(quarantine, worst)}; quarantine table: {kept_at}")
