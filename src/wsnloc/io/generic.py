"""Generic adapter: a run directory of CSV or Parquet tables from any other dataset.

Files (CSV or Parquet, by name; `anchors` and one of `ranges` / `rss` required):
  anchors: anchor_id, tech, x, y [, z]        (m)
  ranges:  t, anchor_id, range_m [, status]   (s, m)
  rss:     t, anchor_id, rss_dbm              (s, dBm)
  imu:     t, ax, ay, az, gz                  (s, m/s^2 body frame, rad/s)
  truth:   t, x, y                            (s, m)
Rows that cannot be used (missing or non-finite numbers, unknown anchors, time going
backwards) go to the quarantine; the line number is the CSV line (header = line 1) or
the Parquet row + 1.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io import tables

COLUMNS = {
    "anchors": (["anchor_id", "tech", "x", "y"], ["z"]),
    "ranges": (["t", "anchor_id", "range_m"], ["status"]),
    "rss": (["t", "anchor_id", "rss_dbm"], []),
    "imu": (["t", "ax", "ay", "az", "gz"], []),
    "truth": (["t", "x", "y"], []),
}
TEXT_COLUMNS = {"anchor_id", "tech"}


def find(run_dir: Path, name: str) -> Path | None:
    for suffix in (".csv", ".parquet"):
        if (run_dir / f"{name}{suffix}").is_file():
            return run_dir / f"{name}{suffix}"
    return None


def _read(path: Path) -> tuple[pd.DataFrame, np.ndarray]:
    """All columns as text plus each row's line number in the file."""
    try:
        if path.suffix == ".csv":
            frame = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
            return frame, np.arange(len(frame)) + 2
        frame = pq.read_table(path).to_pandas().astype(str)
        return frame, np.arange(len(frame)) + 1
    except Exception as exc:  # pandas/pyarrow raise many types for unreadable files
        raise IngestError(f"{path}: cannot read as {path.suffix[1:]} ({exc})") from exc


class _Table:
    """One generic table with row-wise validation into (usable rows, quarantine rows)."""

    def __init__(self, path: Path, name: str):
        self.path, self.name = path, name
        self.frame, self.lines = _read(path)
        required, optional = COLUMNS[name]
        missing = [c for c in required if c not in self.frame.columns]
        if missing:
            raise IngestError(f"{path}: missing column(s) {missing} (expected {required + optional})")
        self.columns = required + [c for c in optional if c in self.frame.columns]
        self.optional = set(optional)
        self.ok = np.ones(len(self.frame), dtype=bool)
        self.reasons = np.full(len(self.frame), "", dtype=object)
        self.values = {}
        for column in self.columns:
            if column in TEXT_COLUMNS:
                text = self.frame[column].str.strip()
                self._reject(text == "", f"{column} is empty")
                self.values[column] = text
            else:
                text = self.frame[column].str.strip()
                number = pd.to_numeric(text, errors="coerce").to_numpy(float)
                bad = ~np.isfinite(number)
                if column in self.optional:          # an optional value may be left empty (NaN)
                    bad &= (text != "").to_numpy()
                self._reject(bad, f"{column} is not a finite number")
                self.values[column] = number

    def _reject(self, mask, reason: str) -> None:
        mask = np.asarray(mask) & self.ok
        self.reasons[mask] = reason
        self.ok &= ~mask

    def known_anchors(self, anchors: set[str]) -> None:
        ids = self.values["anchor_id"].to_numpy()
        self._reject(~np.isin(ids, list(anchors)), "unknown anchor (not in anchors table)")

    def monotonic_time(self) -> None:
        t = np.where(self.ok, self.values["t"], -np.inf)
        previous = np.maximum.accumulate(np.concatenate([[-np.inf], t[:-1]]))
        self._reject(t < previous, "time goes backwards")

    def usable(self) -> pd.DataFrame:
        out = pd.DataFrame({c: (v[self.ok] if isinstance(v, np.ndarray) else v[self.ok].to_numpy())
                            for c, v in self.values.items()})
        out["line"] = self.lines[self.ok].astype(np.int32)
        return out.reset_index(drop=True)

    def quarantined(self) -> list[tuple]:
        raw = self.frame.astype(str).agg(",".join, axis=1).to_numpy()
        return [(self.path.name, int(self.lines[i]), raw[i], self.reasons[i]) for i in np.flatnonzero(~self.ok)]


def ingest_run(run_dir: str | Path, campaign: Campaign) -> tuple[dict[str, pd.DataFrame], dict]:
    """Parse one generic run directory into the canonical tables and an inventory."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise IngestError(f"{run_dir}: not a directory")
    paths = {name: find(run_dir, name) for name in COLUMNS}
    if paths["anchors"] is None:
        raise IngestError(f"{run_dir}: no anchors.csv or anchors.parquet")
    if paths["ranges"] is None and paths["rss"] is None:
        raise IngestError(f"{run_dir}: needs ranges.csv/.parquet or rss.csv/.parquet")
    parsed = {name: _Table(path, name) for name, path in paths.items() if path is not None}
    anchors = parsed["anchors"].usable()
    if "z" not in anchors:
        anchors["z"] = np.nan
    known = set(anchors["anchor_id"])
    for name in ("ranges", "rss"):
        if name in parsed:
            parsed[name].known_anchors(known)
    for name in ("ranges", "rss", "imu", "truth"):
        if name in parsed:
            parsed[name].monotonic_time()
    result = {name: (parsed[name].usable() if name in parsed else tables.empty(name))
              for name in ("ranges", "rss", "imu", "truth")}
    if "status" not in result["ranges"]:
        result["ranges"]["status"] = 0
    result["ranges"]["status"] = result["ranges"]["status"].astype(np.int32)
    if "seq" not in result["rss"]:
        result["rss"]["seq"] = -1
    truth = result["truth"]
    truth["s"] = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(truth["x"]), np.diff(truth["y"])))]) \
        if len(truth) else np.array([], dtype=float)
    result["anchors"] = anchors[["anchor_id", "tech", "x", "y", "z"]]
    rows = [row for table in parsed.values() for row in table.quarantined()]
    result["quarantine"] = pd.DataFrame(rows, columns=["file", "line", "text", "reason"]).astype(
        {"file": str, "line": "int32", "text": str, "reason": str})
    inventory = {p.name: {"sha256": hashlib.sha256(p.read_bytes()).hexdigest(), "lines": len(parsed[n].frame) + 1,
                          "data_lines": len(parsed[n].frame), "quarantined": int((~parsed[n].ok).sum())}
                 for n, p in paths.items() if p is not None}
    return result, inventory
