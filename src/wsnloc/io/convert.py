"""Converters from public datasets' own layouts into the generic format.

cucudasluv/UWB-dataset (Hanyang University, Apache-2.0): per-anchor ROS exports
`A<id>.csv` (`%time,field.stamp,field.id,field.x,field.y,field.z,field.distanceFromTag,
field.rssi,field.rssi_fp`, stamps in ns) and `trajectory.csv` (`timestamp,x,y,z,
heading_degrees`, RTK-GNSS in the anchors' frame). Each case becomes a generic run
<out>/<los|nlos>/<trajectory>-<case>/ with anchors, ranges, rss and truth CSV files, and the
case's published baselines beside them as reference tables (published_LS.csv, published_ESKF.csv:
t, x, y; published_values.csv: the RMSD_results.txt values; see wsnloc.references).

philotuxo/Position-Annotated-BLE-RSSI-Dataset (Bogazici University, CC0): receivers in
`cnf/tetam.dev` (`Dongles:{"MAC": [[x, y, z], colour, "name"], ...}`, metres) and merged
tracks `trk/<track>_all_sensors.mbd` (`timestamp, MAC sensor, MAC beacon, RSSI, x, y, z,
r11..r33`: Unix s, dBm, camera truth in m). The receivers are the anchors (tech `ble`,
named by the file's sensor names), the beacon is the tag; each track becomes a generic run
<out>/tracks/<track>/ with anchors, rss and truth (truth from the camera annotation of
every line, one row per distinct time).

Every run also gets a `meta.yaml` with the tag's antenna height `tag_height_m` (m) as the
dataset documents it, so that 3-D ranges / distances to anchors with z are right without a
campaign file (generic.run_campaign). Source lines that cannot be converted (wrong number
of fields, a value that is not a finite number, a negative range, an unknown receiver or
beacon) are written to the run's `convert_quarantine.csv` (file, line, text, reason) and
counted in what the converter returns; a source file with more than
`limits.DEFAULT_PER_FILE` of its lines quarantined stops the conversion (IngestError
naming the file and its first bad line). The source files are only read.
"""

from __future__ import annotations

import csv
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc.errors import IngestError
from wsnloc.io.csvrows import read_csv_rows
from wsnloc.io.limits import DEFAULT_PER_FILE

NS = 1e-9
QUARANTINE_FILE = "convert_quarantine.csv"
# Tag (mobile antenna) heights as the datasets' documentation gives them (m)
CUCUDASLUV_TAG_HEIGHT_M = 1.0     # cucudasluv PROVENANCE / README: tag about 1.0 m above ground
PHILOTUXO_TAG_HEIGHT_M = 1.8      # philotuxo PROVENANCE: beacon carried at about 1.8 m
PHILOTUXO_BEACON = "e78f135624ce"  # philotuxo PROVENANCE: the one beacon of the tracks


@dataclass
class Converted:
    """One converted run: its directory and the source lines quarantined (file, line, text, reason)."""

    run_dir: Path
    quarantine: list[tuple[str, int, str, str]] = field(default_factory=list)

    def __fspath__(self) -> str:      # usable wherever a path is
        return str(self.run_dir)


class _Source:
    """Row checks of one source file: usable rows, or (file, line, text, reason) in the quarantine."""

    def __init__(self, path: Path, quarantine: list):
        self.path, self.quarantine, self.n_lines, self.n_bad = path, quarantine, 0, 0

    def refuse(self, line: int, text: str, reason: str) -> None:
        self.quarantine.append((self.path.name, int(line), text, reason))
        self.n_bad += 1

    def check(self) -> None:
        """Stop when more than DEFAULT_PER_FILE of the file's lines were quarantined."""
        if self.n_lines and self.n_bad / self.n_lines > DEFAULT_PER_FILE:
            first = next(q for q in self.quarantine if q[0] == self.path.name)
            raise IngestError(f"{self.path}:{first[1]}: {self.n_bad} of {self.n_lines} lines cannot be converted "
                              f"(first: {first[3]}); over the {DEFAULT_PER_FILE:.0%} limit")


def _numbers(source: _Source, rows, columns: list[str], non_negative: tuple[str, ...] = (),
             passed_on: tuple[str, ...] = ()) -> pd.DataFrame:
    """The named columns of a read_csv_rows result as floats; rows with a value that is not a
    finite number (or negative, for `non_negative`) go to the quarantine. `passed_on` columns
    are not checked: a bad value (NaN, inf) goes into the generic table as it is, whose ingest
    quarantines that row of that table alone (a valid range is not lost for a bad RSSI)."""
    source.n_lines += rows.n_records
    for line, text, reason in rows.refused:
        source.refuse(line, text, reason)
    missing = [c for c in columns if c not in rows.frame.columns]
    if missing:
        raise IngestError(f"{source.path}:1: missing column(s) {missing}")
    values = {c: pd.to_numeric(rows.frame[c].str.strip(), errors="coerce").to_numpy(float) for c in columns}
    values.update({c: pd.to_numeric(rows.frame[c].str.strip(), errors="coerce").to_numpy(float) for c in passed_on
                   if c in rows.frame.columns})
    ok = np.ones(len(rows.frame), dtype=bool)
    for c in columns:
        bad = ~np.isfinite(values[c]) | ((values[c] < 0) if c in non_negative else False)
        for i in np.flatnonzero(bad & ok):     # the line's text is rebuilt for the (few) refused rows only
            kind = "negative" if np.isfinite(values[c][i]) else "not a finite number"
            text = ",".join(rows.frame.iloc[i].astype(str))
            source.refuse(rows.lines[i], text, f"{c} {rows.frame[c].iloc[i]!r} is {kind}")
        ok &= ~bad
    return pd.DataFrame({c: v[ok] for c, v in values.items()})


def _write_csv(frame: pd.DataFrame, path: Path) -> None:
    """frame.to_csv(path, index=False, float_format="%.9f"), the same bytes at about a third of
    the CPU: each float column formatted by one list comprehension ("%.9f", "" for NaN), integer
    and string columns by str, the rows written by the csv module's writer, as pandas does
    (minimal quoting, "\n" line ends). A frame with columns of other types (a string column
    with missing values, booleans, dates) is written by to_csv."""
    columns = []
    for name in frame.columns:
        values = frame[name]
        if pd.api.types.is_float_dtype(values):
            columns.append(["" if v != v else "%.9f" % v for v in values.tolist()])
        elif pd.api.types.is_integer_dtype(values) and not values.hasnans \
                or pd.api.types.is_string_dtype(values) and not values.hasnans \
                and all(isinstance(v, str) for v in values.tolist()):
            columns.append([str(v) for v in values.tolist()])
        else:
            frame.to_csv(path, index=False, float_format="%.9f")
            return
    with open(path, "w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out, lineterminator=os.linesep)
        writer.writerow([str(c) for c in frame.columns])
        writer.writerows(zip(*columns))


def _write_run(target: Path, tables: dict[str, pd.DataFrame], tag_height_m: float, source: str,
               quarantine: list) -> Converted:
    target.mkdir(parents=True, exist_ok=True)
    for name, frame in tables.items():
        _write_csv(frame, target / f"{name}.csv")
    (target / "meta.yaml").write_text(f"# converted from {source}\ntag_height_m: {tag_height_m}\n")
    pd.DataFrame(quarantine, columns=["file", "line", "text", "reason"]).to_csv(target / QUARANTINE_FILE, index=False)
    return Converted(target, quarantine)


# ---- cucudasluv ------------------------------------------------------------------------------
def _case_dirs(src: Path):
    for trajectory_csv in sorted(src.glob("Dynamic_measurements/*/*/*/trajectory.csv")):
        case = trajectory_csv.parent
        yield case.parents[1].name.lower(), f"{case.parent.name}-{case.name}".lower().replace("_", "-"), case


_RMSD_LINE = re.compile(r"^\s*(\w+ RMSE(?:_2d)?)\s*:\s*([-+0-9.eE]+)")


def _published(case: Path, quarantine: list) -> dict[str, pd.DataFrame]:
    """The case's own baselines as reference tables (references.published_tracks / _values):
    published_LS / published_ESKF (t s, x, y m) and published_values (name, value) from
    RMSD_results.txt ("LS RMSE_2d: 1.04" -> name "LS RMSE_2d")."""
    out = {}
    for name in ("LS", "ESKF"):
        path = case / f"{name}.csv"
        if path.is_file():
            source = _Source(path, quarantine)
            track = _numbers(source, read_csv_rows(path), ["timestamp", "x", "y"])
            source.check()
            out[f"published_{name}"] = pd.DataFrame({"t": track["timestamp"].astype("int64") * NS,
                                                     "x": track["x"], "y": track["y"]})
    path = case / "RMSD_results.txt"
    if path.is_file():
        values = [m.groups() for m in map(_RMSD_LINE.match, path.read_text().splitlines()) if m]
        out["published_values"] = pd.DataFrame([(k, float(v)) for k, v in values], columns=["name", "value"])
    return out


def convert_cucudasluv(src: str | Path, out: str | Path, ranges_only: bool = False) -> list[Converted]:
    """Convert every dynamic case; returns the runs written. ranges_only: the anchors, ranges and
    truth tables alone (no rss table, no published baselines), all that range errors read."""
    src, out = Path(src), Path(out)
    written = []
    for scenario, run, case in _case_dirs(src):
        quarantine: list = []
        anchors, ranges, rss = [], [], []
        for path in sorted(case.glob("A*.csv"), key=lambda p: int(p.stem[1:])):
            source = _Source(path, quarantine)
            data = _numbers(source, read_csv_rows(path), ["field.stamp", "field.x", "field.y", "field.z",
                                                          "field.distanceFromTag"],
                            non_negative=("field.distanceFromTag",), passed_on=("field.rssi",))
            source.check()
            if data.empty:
                continue
            anchor_id = path.stem
            first = data.iloc[0]
            anchors.append((anchor_id, "uwb", first["field.x"], first["field.y"], first["field.z"]))
            t = data["field.stamp"].astype("int64") * NS
            ranges.append(pd.DataFrame({"t": t, "anchor_id": anchor_id, "range_m": data["field.distanceFromTag"]}))
            rss.append(pd.DataFrame({"t": t, "anchor_id": anchor_id, "rss_dbm": data["field.rssi"]}))
        if not anchors:
            raise IngestError(f"{case}: no per-anchor A<id>.csv files with data")
        source = _Source(case / "trajectory.csv", quarantine)
        truth = _numbers(source, read_csv_rows(case / "trajectory.csv"), ["timestamp", "x", "y"])
        source.check()
        tables = {"anchors": pd.DataFrame(anchors, columns=["anchor_id", "tech", "x", "y", "z"]),
                  "ranges": pd.concat(ranges).sort_values("t", kind="stable"),
                  "truth": pd.DataFrame({"t": truth["timestamp"].astype("int64") * NS, "x": truth["x"],
                                         "y": truth["y"]})}
        if not ranges_only:
            tables.update(rss=pd.concat(rss).sort_values("t", kind="stable"), **_published(case, quarantine))
        written.append(_write_run(out / scenario / run, tables, CUCUDASLUV_TAG_HEIGHT_M, "cucudasluv/UWB-dataset",
                                  quarantine))
    if not written:
        raise IngestError(f"{src}: no Dynamic_measurements/*/*/*/trajectory.csv found")
    return written


# ---- philotuxo BLE RSSI --------------------------------------------------------------------------
def read_receivers(path: Path) -> pd.DataFrame:
    """The receivers of a `.dev` file (`Dongles:{...}` line) as an anchors table (tech ble)."""
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        if line.startswith("Dongles:"):
            try:
                dongles = json.loads(line.split(":", 1)[1])
                rows = [(name, "ble", *map(float, xyz), mac) for mac, ([*xyz], _, name) in dongles.items()]
            except (ValueError, TypeError) as exc:
                raise IngestError(f"{path}:{number}: cannot read the receivers ({exc})") from exc
            if any(len(r) != 6 for r in rows):
                raise IngestError(f"{path}:{number}: a receiver has no [x, y, z] position")
            return pd.DataFrame(rows, columns=["anchor_id", "tech", "x", "y", "z", "mac"])
    raise IngestError(f"{path}: no 'Dongles:' line listing the receivers")


_TRACK = re.compile(r"(.*)_all_sensors$")


def _track_name(path: Path) -> str:
    match = _TRACK.match(path.stem)
    return (match.group(1) if match else path.stem).lower().replace("_", "-")


def _read_track(path: Path, receivers: pd.DataFrame, quarantine: list) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(rss, truth) of one merged track file; bad lines to the quarantine."""
    source = _Source(path, quarantine)
    by_mac = dict(zip(receivers["mac"], receivers["anchor_id"]))
    rss, truth = [], []
    for number, raw in enumerate(path.read_bytes().split(b"\n"), start=1):
        text = raw.decode("utf-8", errors="replace").strip()
        if not text or text.startswith("#"):
            continue
        source.n_lines += 1
        fields = [f.strip() for f in text.split(",")]
        if len(fields) != 16:
            source.refuse(number, text, f"{len(fields)} fields, expected 16 (timestamp, sensor, beacon, RSSI, "
                                        f"x, y, z, 9 orientation values)")
            continue
        try:
            t, value, x, y = float(fields[0]), float(fields[3]), float(fields[4]), float(fields[5])
        except ValueError:
            source.refuse(number, text, "timestamp, RSSI, x or y is not a number")
            continue
        if not np.isfinite([t, value, x, y]).all():
            source.refuse(number, text, "timestamp, RSSI, x or y is not finite")
        elif fields[2] != PHILOTUXO_BEACON:
            source.refuse(number, text, f"beacon {fields[2]!r} is not the tracked beacon {PHILOTUXO_BEACON}")
        elif fields[1] not in by_mac:
            source.refuse(number, text, f"unknown receiver {fields[1]!r} (not in the .dev file)")
        else:
            rss.append((t, by_mac[fields[1]], value))
            truth.append((t, x, y))
    source.check()
    rss = pd.DataFrame(rss, columns=["t", "anchor_id", "rss_dbm"]).sort_values("t", kind="stable")
    truth = pd.DataFrame(truth, columns=["t", "x", "y"]).sort_values("t", kind="stable")
    return rss, truth.drop_duplicates("t")


def convert_philotuxo(src: str | Path, out: str | Path) -> list[Converted]:
    """Convert every merged track `trk/*_all_sensors.mbd`; returns the runs written."""
    src, out = Path(src), Path(out)
    devices = sorted(src.glob("cnf/*.dev"))
    if len(devices) != 1:
        raise IngestError(f"{src}/cnf: expected one .dev receiver file, found {len(devices)}")
    receivers = read_receivers(devices[0])
    written = []
    for path in sorted(src.glob("trk/*_all_sensors.mbd")):
        quarantine: list = []
        rss, truth = _read_track(path, receivers, quarantine)
        if rss.empty:
            raise IngestError(f"{path}: no usable RSSI line")
        tables = {"anchors": receivers.drop(columns="mac"), "rss": rss, "truth": truth}
        written.append(_write_run(out / "tracks" / _track_name(path), tables, PHILOTUXO_TAG_HEIGHT_M,
                                  "philotuxo/Position-Annotated-BLE-RSSI-Dataset", quarantine))
    if not written:
        raise IngestError(f"{src}: no trk/*_all_sensors.mbd track found")
    return written


CONVERTERS = {"cucudasluv": convert_cucudasluv, "philotuxo": convert_philotuxo}

# ---- the workflow's view: runs and files a conversion will write, known before it runs -------------
RUN_FILES = {"cucudasluv": ("anchors.csv", "ranges.csv", "rss.csv", "truth.csv", "meta.yaml"),
             "philotuxo": ("anchors.csv", "rss.csv", "truth.csv", "meta.yaml")}


def run_names(dataset: str, src: str | Path) -> dict[str, list[str]]:
    """{scenario: [run]} that CONVERTERS[dataset] writes from src (from the source's layout alone)."""
    src = Path(src)
    if dataset == "cucudasluv":
        out: dict[str, list[str]] = {}
        for scenario, run, _ in _case_dirs(src):
            out.setdefault(scenario, []).append(run)
        return out
    return {"tracks": [_track_name(p) for p in sorted(src.glob("trk/*_all_sensors.mbd"))]}
