"""Generic adapter: a run directory of CSV or Parquet tables from any other dataset.

Files (CSV or Parquet, by name; `anchors` and one of `ranges` / `rss` / `tdoa` required):
  anchors: anchor_id, tech, x, y [, z]        (m)
  ranges:  t, anchor_id, range_m [, status]   (s, m)
  rss:     t, anchor_id, rss_dbm              (s, dBm)
  tdoa:    t, anchor_id, ref_anchor_id, tdoa_m (s, m: range difference d(anchor) - d(ref), one
           row per pair; pairs of one time stamp are one measurement, see docs/raw-formats.md)
  imu:     t, ax, ay, az, gz                  (s, m/s^2 body frame, rad/s)
  truth:   t, x, y [, z]                      (s, m; z: the tag's height, for 3-D metrics)
  odometry: t, v_mps, yaw_rate_rps            (s, m/s forward speed, rad/s counter-clockwise;
                                               body frame: the odometry motion model's input)
  meta.yaml (optional): tag_height_m          (m: the mobile's antenna height, for 3-D
                                               ranges to anchors with z; see run_campaign)
Rows that cannot be used go to the quarantine with file, line and a reason naming the
value: CSV rows with the wrong number of fields or cut off at the end of the file
(wsnloc.io.csvrows), missing or non-finite numbers, negative ranges, anchors missing
from the anchors table (also counted per anchor in the inventory), a TDOA pair whose
anchor is its own reference, a time stamp more than MAX_RUN_S (a day) from the file's median
time (a clock reset, a zero or corrupt stamp), a row repeating an earlier row value for value (a
record logged twice: counted twice otherwise; the first stays). The line number is
the CSV line (header = line 1) or the Parquet row + 1. Rows need not be sorted: each
table is sorted by time (stable), and the number of rows out of order is reported.
Refused with IngestError naming the file: a missing column, an anchors, ranges, rss or
tdoa table with no data row, a duplicate anchor id. No campaign is needed.
"""

from __future__ import annotations

import hashlib
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml
from wsnloc.errors import IngestError
from wsnloc.io import tables
from wsnloc.io.csvrows import CsvRows, read_csv_rows
from wsnloc.io.timeorder import longest_ordered

COLUMNS = {
    "anchors": (["anchor_id", "tech", "x", "y"], ["z"]),
    "ranges": (["t", "anchor_id", "range_m"], ["status"]),
    "rss": (["t", "anchor_id", "rss_dbm"], []),
    "tdoa": (["t", "anchor_id", "ref_anchor_id", "tdoa_m"], []),
    "imu": (["t", "ax", "ay", "az", "gz"], []),
    "truth": (["t", "x", "y"], ["z"]),
    "odometry": (["t", "v_mps", "yaw_rate_rps"], []),
}
TEXT_COLUMNS = {"anchor_id", "ref_anchor_id", "tech"}
NON_NEGATIVE_COLUMNS = {"range_m"}
NEVER_EMPTY = ("anchors", "ranges", "rss", "tdoa")     # a run without their rows has nothing to localise with
MAX_RUN_S = 86400.0    # s: a run's stamps lie within a day of its median time (a longer campaign: split it into runs)
# s: the largest plausible median time stamp, Unix seconds in the year 5138; above it the stamps are in a
# finer unit (Unix milliseconds are ~1.7e12, microseconds ~1.7e15, nanoseconds ~1.7e18)
MAX_SECONDS = 1e11
FINER_UNITS = ((1e17, "nanoseconds", 1e9), (1e14, "microseconds", 1e6), (MAX_SECONDS, "milliseconds", 1e3))
SECONDS_PER_YEAR = 3.15576e7   # s: a Julian year


def run_campaign(run_dir: str | Path) -> Campaign | None:
    """The site facts a generic run carries itself: a campaign with the `tag_height_m` of the
    run's optional meta.yaml (m), or None without one. A campaign file, when given, is used
    instead (its tag_height_m applies)."""
    path = Path(run_dir) / "meta.yaml"
    if not path.is_file():
        return None
    meta = read_yaml(path) or {}
    height = meta.get("tag_height_m")
    if height is None:
        return None
    if not isinstance(height, (int, float)) or not np.isfinite(height):
        raise IngestError(f"{path}: key 'tag_height_m' must be a number (m), not {height!r}")
    return Campaign(name=f"generic run {Path(run_dir).name}", format="generic",
                    spec={"tag_height_m": float(height)}, source=str(path))


def find(run_dir: Path, name: str) -> Path | None:
    for suffix in (".csv", ".parquet"):
        if (run_dir / f"{name}{suffix}").is_file():
            return run_dir / f"{name}{suffix}"
    return None


def _read(path: Path) -> CsvRows:
    """A CSV file row by row, or a Parquet file whole (its rows cannot be damaged apart)."""
    if path.suffix == ".csv":
        return read_csv_rows(path)
    try:
        values = pq.read_table(path).to_pandas()
    except Exception as exc:  # pyarrow raises many types for unreadable files
        raise IngestError(f"{path}: cannot read as parquet ({exc})") from exc
    frame = values.astype(str).where(values.notna(), "")      # a missing value reads as an empty CSV field
    return CsvRows(frame, np.arange(len(frame)) + 1, [], len(frame), len(frame))


class _Table:
    """One generic table with row-wise validation into (usable rows, quarantine rows)."""

    def __init__(self, path: Path, name: str):
        self.path, self.name = path, name
        read = _read(path)
        self.frame, self.lines, self.refused = read.frame, read.lines, read.refused
        self.n_lines, self.n_records = read.n_lines, read.n_records
        required, optional = COLUMNS[name]
        missing = [c for c in required if c not in self.frame.columns]
        if missing:
            raise IngestError(f"{path}: missing column(s) {missing} (expected {required + optional})")
        if name in NEVER_EMPTY and self.n_records == 0:
            raise IngestError(f"{path}: no data rows (the {name} table is required; leave an empty "
                              f"{'ranges, rss or tdoa ' if name != 'anchors' else ''}file out of the run)")
        self.columns = required + [c for c in optional if c in self.frame.columns]
        self.ok = np.ones(len(self.frame), dtype=bool)
        self.reasons = np.full(len(self.frame), "", dtype=object)
        self.values = {}
        self.reordered = 0
        for column in self.columns:
            text = self.frame[column].str.strip()
            if column in TEXT_COLUMNS:
                self._reject(text == "", text, f"{column} is empty")
                self.values[column] = text.to_numpy(dtype=object)
                continue
            number = pd.to_numeric(text, errors="coerce").to_numpy(float)
            bad = ~np.isfinite(number)
            if column in optional:          # an optional value may be left empty (NaN)
                bad &= (text != "").to_numpy()
            self._reject(bad, text, f"{column} {{value!r}} is not a finite number")
            if column in NON_NEGATIVE_COLUMNS:
                self._reject(number < 0, text, f"{column} {{value!r}} is negative")
            self.values[column] = number
        if "t" in self.values:
            self._time_unit()
            self._far_times(self.frame["t"].str.strip())

    def _time_unit(self) -> None:
        """Stop on time stamps that are not seconds: a median above MAX_SECONDS (a logger's Unix
        milliseconds, micro- or nanoseconds read as seconds would put the run thousands of years
        ahead, and its rates a thousand times too low)."""
        t = self.values["t"][self.ok & np.isfinite(self.values["t"])]
        centre = float(np.median(t)) if len(t) else 0.0
        for above, unit, per_second in FINER_UNITS:
            if abs(centre) > above:
                raise IngestError(f"{self.path}: column t must be in seconds; its median {centre:.6g} looks like "
                                  f"Unix {unit} or a finer unit than seconds (as seconds, year "
                                  f"{1970 + centre / SECONDS_PER_YEAR:.0f}): divide t by {per_second:.0f} (and the "
                                  f"other tables' t alike)")

    def _far_times(self, text: pd.Series) -> None:
        """Refuse rows whose time stamp lies more than MAX_RUN_S from the median time of the table's
        usable rows: a clock reset, a zero or a corrupt stamp (one row at t = 0 among Unix times
        would stretch the run over 55 years: an epoch grid of 3e9 periods)."""
        t = self.values["t"]
        usable = self.ok & np.isfinite(t)
        if not usable.any():
            return
        centre = float(np.median(t[usable]))
        self._reject(np.abs(t - centre) > MAX_RUN_S, text,
                     f"t {{value!r}} is more than {MAX_RUN_S:.0f} s from the median time of the file "
                     f"({centre:.3f} s): a clock reset or a corrupt time stamp")

    def refuse_repeats(self) -> None:
        """Refuse a row of a timed table whose every value equals an earlier usable row's: a record
        logged twice (kept, it would count twice); the first one stays. Run after the other checks,
        so that a refused row keeps its own reason."""
        if "t" not in self.values:
            return
        usable = np.flatnonzero(self.ok)
        frame = pd.DataFrame({c: v[usable] for c, v in self.values.items()})
        key = pd.util.hash_pandas_object(frame, index=False).to_numpy()
        _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
        repeat = np.arange(len(key)) != first[inverse]
        first_line = np.full(len(self.ok), "", dtype=object)
        first_line[usable[repeat]] = self.lines[usable[first[inverse[repeat]]]].astype(str)
        mask = np.zeros(len(self.ok), dtype=bool)
        mask[usable[repeat]] = True
        self._reject(mask, pd.Series(first_line), "a repeat of line {value} (every value equal)")

    def _reject(self, mask, text: pd.Series, reason: str) -> None:
        """Refuse the rows of `mask` not refused yet; `reason` may name the row's {value}."""
        rows = np.flatnonzero(np.asarray(mask) & self.ok)
        values = text.to_numpy(dtype=object)[rows]
        self.reasons[rows] = [reason.format(value=value) for value in values]
        self.ok[rows] = False

    def known_anchors(self, anchors: set[str], anchors_file: str) -> dict[str, int]:
        """Refuse rows whose anchor (and reference anchor, in a TDOA table) is not in the anchors
        table, and TDOA pairs whose anchor is its own reference; returns the count per unknown anchor."""
        counts: Counter = Counter()
        for column in [c for c in ("anchor_id", "ref_anchor_id") if c in self.values]:
            ids = self.values[column]
            unknown = ~np.isin(ids, list(anchors)) & self.ok
            what = "reference anchor" if column == "ref_anchor_id" else "anchor"
            self._reject(unknown, pd.Series(ids), f"unknown {what} {{value!r}} (not in {anchors_file})")
            counts.update(ids[unknown].tolist())
        if "ref_anchor_id" in self.values:
            same = self.values["anchor_id"] == self.values["ref_anchor_id"]
            self._reject(same, pd.Series(self.values["anchor_id"]),
                         "anchor {value!r} is its own reference (a range difference needs two anchors)")
        return dict(counts)

    def usable(self) -> pd.DataFrame:
        """The rows kept, sorted by time (stable) when the table has one; counts `reordered`."""
        out = pd.DataFrame({c: v[self.ok] for c, v in self.values.items()})
        out["line"] = self.lines[self.ok].astype(np.int32)
        if "t" in out:
            self.reordered = int((~longest_ordered(out["t"].to_numpy(), strict=False)).sum())
            if self.reordered:
                out = out.sort_values("t", kind="stable")
        return out.reset_index(drop=True)

    def quarantined(self) -> list[tuple]:
        bad = np.flatnonzero(~self.ok)
        texts = self.frame.iloc[bad].astype(str).agg(",".join, axis=1).to_numpy() if len(bad) else []
        rows = [(self.path.name, int(self.lines[i]), text, self.reasons[i]) for i, text in zip(bad, texts)]
        rows += [(self.path.name, line, text, reason) for line, text, reason in self.refused]
        return sorted(rows, key=lambda row: row[1])

    def inventory(self) -> dict:
        return {"sha256": hashlib.sha256(self.path.read_bytes()).hexdigest(), "lines": self.n_lines,
                "data_lines": self.n_records, "quarantined": int((~self.ok).sum()) + len(self.refused),
                "reordered": self.reordered}


def tdoa_beside(path: Path, anchors: pd.DataFrame, anchors_source: str) -> tuple[pd.DataFrame, list, dict]:
    """A tdoa table beside another format's logs (the simulator's one-way UWB TDOA), read with
    this reader's rules against the campaign's anchors (`anchors_source` names where they are):
    (usable rows, quarantine rows (file, line, text, reason), inventory entry)."""
    table = _Table(path, "tdoa")
    unknown = table.known_anchors(set(anchors["anchor_id"]), anchors_source)
    table.refuse_repeats()
    usable, inventory = table.usable(), table.inventory()
    return usable, table.quarantined(), {**inventory, **({"unknown_anchors": unknown} if unknown else {})}


def _unique_anchors(table: _Table, anchors: pd.DataFrame) -> None:
    """A duplicate anchor id makes every later lookup ambiguous: refuse the file."""
    repeated = anchors["anchor_id"][anchors["anchor_id"].duplicated()]
    if len(repeated):
        anchor = repeated.iloc[0]
        lines = anchors.loc[anchors["anchor_id"] == anchor, "line"].tolist()
        raise IngestError(f"{table.path}: duplicate anchor id {anchor!r} (lines {', '.join(map(str, lines))})")


def ingest_run(run_dir: str | Path, campaign: Campaign | None = None) -> tuple[dict[str, pd.DataFrame], dict]:
    """Parse one generic run directory into the canonical tables and an inventory.

    The campaign is not needed (walls and tag height matter only to the estimators).
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise IngestError(f"{run_dir}: not a directory")
    paths = {name: find(run_dir, name) for name in COLUMNS}
    if paths["anchors"] is None:
        raise IngestError(f"{run_dir}: no anchors.csv or anchors.parquet")
    if paths["ranges"] is None and paths["rss"] is None and paths["tdoa"] is None:
        raise IngestError(f"{run_dir}: needs ranges.csv/.parquet, rss.csv/.parquet or tdoa.csv/.parquet")
    parsed = {name: _Table(path, name) for name, path in paths.items() if path is not None}
    anchors = parsed["anchors"].usable()
    _unique_anchors(parsed["anchors"], anchors)
    if "z" not in anchors:
        anchors["z"] = np.nan
    unknown = {name: parsed[name].known_anchors(set(anchors["anchor_id"]), paths["anchors"].name)
               for name in ("ranges", "rss", "tdoa") if name in parsed}
    for table in parsed.values():
        table.refuse_repeats()
    result = {name: (parsed[name].usable() if name in parsed else tables.empty(name))
              for name in ("ranges", "rss", "tdoa", "imu", "truth", "odometry")}
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
    inventory = {paths[name].name: table.inventory() for name, table in parsed.items()}
    for name, counts in unknown.items():
        if counts:
            inventory[paths[name].name]["unknown_anchors"] = counts
    return result, inventory
