"""Parsers for the Newcom++-style raw logs (uwb.log, zigbee.log, imu.log, truth.log).

Formats: shared/spec/raw-formats.md. Each parser returns a DataFrame in SI units
(seconds, metres, dBm, m/s^2, rad/s) and sends every unusable line to the quarantine
with a reason. UWB records with a non-zero status are kept, with their status, so that
estimators can apply the preliminary filter.
"""

from __future__ import annotations

import io
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io import generic, tables
from wsnloc.io.rawlines import Quarantine, RawFile, check_magic, header_value, iter_fields, read_raw
from wsnloc.io.timeorder import in_order, keep_in_time_order, longest_ordered, out_of_order_reasons

FILES = ("uwb.log", "zigbee.log", "imu.log", "truth.log")
TRUTH_TOLERANCE_M = 0.05


class _LineError(ValueError):
    """A reason why one line is unusable."""


def _finite(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _LineError(f"{what} is not a number: {text!r}") from None
    if not math.isfinite(value):
        raise _LineError(f"{what} is not finite: {text!r}")
    return value


def _integer(text: str, what: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise _LineError(f"{what} is not an integer: {text!r}") from None


# The bytes a plain numeric log may hold for the bulk path: with only these, a token is
# accepted by pyarrow's float64 / int64 parsers exactly when float() / int() accept it, with
# the same value (both round a decimal to the nearest double); "nan", "inf", "1e3", "+1",
# "1_0" and any other byte send the file to the per-line checks, which give the reasons.
_NUMERIC_BYTES = b"0123456789.- \n"


def _plain_numbers(raw: RawFile, columns: dict[str, pa.DataType]) -> dict[str, np.ndarray] | None:
    """The columns of a plain log (rawlines.plain_body) whose every line is len(columns)
    numbers separated by single spaces, parsed in bulk; None when the file is not such a
    log (a line with another field count or a token that does not parse included) or a
    number overflows to infinity (float() gives inf too; the per-line checks refuse it)."""
    if raw.plain is None or raw.plain.translate(None, _NUMERIC_BYTES):
        return None
    options = {"read_options": pacsv.ReadOptions(column_names=list(columns), use_threads=False),
               "parse_options": pacsv.ParseOptions(delimiter=" ", quote_char=False, ignore_empty_lines=False),
               "convert_options": pacsv.ConvertOptions(column_types=columns, null_values=[],
                                                       strings_can_be_null=False, quoted_strings_can_be_null=False)}
    try:
        table = pacsv.read_csv(io.BytesIO(raw.plain), **options)
    except pa.ArrowInvalid:
        return None
    numbers = {name: table.column(name).to_numpy() for name in columns}
    return numbers if all(np.all(np.isfinite(numbers[name])) for name, kind in columns.items()
                          if pa.types.is_floating(kind)) else None


def _plain_line_numbers(raw: RawFile) -> np.ndarray:
    """Line numbers (int64) of the data lines of a plain log: consecutive from its first."""
    return np.arange(raw.first_line, raw.first_line + raw.n_records, dtype=np.int64)


def _anchor(anchor_id: str, techs: dict[str, str], tech: str) -> str:
    known = techs.get(anchor_id)
    if known is None:
        raise _LineError(f"unknown anchor {anchor_id!r} (not in the campaign file)")
    if known != tech:
        raise _LineError(f"anchor {anchor_id!r} is a {known} anchor, not {tech}")
    return anchor_id


def parse_uwb(raw: RawFile, campaign: Campaign, quarantine: Quarantine) -> pd.DataFrame:
    """uwb.log: `t_ms anchor tw_toa_ps status`; range = c * tw_toa / 2 (m)."""
    check_magic(raw, "-uwb")
    c = campaign.spec["speed_of_light_mps"]
    techs = dict(zip(campaign.anchors["anchor_id"], campaign.anchors["tech"]))
    plain = _uwb_plain(raw, c, {anchor for anchor, tech in techs.items() if tech == "uwb"})
    return plain if plain is not None else _uwb_lines(raw, c, techs, quarantine)


# A uwb.log line the bulk path reads: single spaces, plain decimal t_ms, an anchor without
# spaces, tw_toa_ps and status of at most 9 digits (integers a double holds exactly, so
# c * tw_toa_ps rounds as in Python). On these tokens pyarrow's casts give float() / int()
# exactly (see _ZIGBEE_LINE).
_UWB_LINE = r"^(?P<t_ms>-?[0-9]+(?:\.[0-9]+)?) (?P<anchor>[^ ]+) (?P<tw>-?[0-9]{1,9}) (?P<status>-?[0-9]{1,9})$"


def _plain_lines(raw: RawFile) -> pa.Array:
    """The data lines of a plain log (raw.plain) as an Arrow string array."""
    return pa.array(raw.plain.decode("ascii").split("\n")[:raw.n_records])


def _uwb_plain(raw: RawFile, c: float, anchors: set[str]) -> pd.DataFrame | None:
    """The ranges of a clean uwb.log, read in bulk by pyarrow (the same values as the per-line
    path, range = c * tw_toa_ps * 1e-12 / 2.0 in that order); None when a line is not a
    _UWB_LINE, names an anchor that is not a uwb anchor, has a t_ms that is not finite or
    goes back in time, or when c is not a float (Python multiplies an integer c exactly)."""
    if raw.plain is None or not isinstance(c, float):
        return None
    fields = pc.extract_regex(_plain_lines(raw), _UWB_LINE)
    known = pc.is_in(fields.field("anchor"), value_set=pa.array(sorted(anchors), type=pa.string()))
    if fields.null_count or not pc.all(known).as_py():
        return None
    t_ms, tw, status = (pc.cast(fields.field(name), kind).to_numpy()
                        for name, kind in (("t_ms", pa.float64()), ("tw", pa.int64()), ("status", pa.int64())))
    if not (np.all(np.isfinite(t_ms)) and in_order(t_ms, strict=False)):
        return None
    return pd.DataFrame({"t": t_ms / 1000.0, "anchor_id": pd.array(fields.field("anchor"), dtype="str"),
                         "range_m": c * tw * 1e-12 / 2.0, "status": status, "line": _plain_line_numbers(raw)})


def _uwb_lines(raw: RawFile, c: float, techs: dict[str, str], quarantine: Quarantine) -> pd.DataFrame:
    """The ranges of the usable lines of a uwb.log, checked one by one (unusable ones quarantined)."""
    accepted, rejected = [], []
    for number, text, fields in iter_fields(raw):
        try:
            if len(fields) != 4:
                raise _LineError(f"expected 4 fields 't_ms anchor tw_toa_ps status', found {len(fields)}")
            t_ms = _finite(fields[0], "t_ms")
            anchor = _anchor(fields[1], techs, "uwb")
            tw_toa_ps = _integer(fields[2], "tw_toa_ps")
            status = _integer(fields[3], "status")
        except _LineError as reason:
            rejected.append((number, text, str(reason)))
            continue
        accepted.append((number, text, t_ms, (t_ms / 1000.0, anchor, c * tw_toa_ps * 1e-12 / 2.0, status, number)))
    rows = keep_in_time_order(raw.name, accepted, rejected, quarantine, strict=False)
    return pd.DataFrame(rows, columns=["t", "anchor_id", "range_m", "status", "line"]) if rows else tables.empty("ranges")


def parse_zigbee(raw: RawFile, campaign: Campaign, quarantine: Quarantine) -> pd.DataFrame:
    """zigbee.log: `t_ms seq n anchor:rssi_dbm ...` with n matching the number of pairs."""
    check_magic(raw, "-zigbee")
    techs = dict(zip(campaign.anchors["anchor_id"], campaign.anchors["tech"]))
    plain = _zigbee_plain(raw, {anchor for anchor, tech in techs.items() if tech == "zigbee"})
    return plain if plain is not None else _zigbee_lines(raw, techs, quarantine)


# A zigbee.log line the bulk path reads: single spaces, plain decimal t_ms, integer seq, n and
# rssi, and at least one anchor:rssi pair whose anchor has neither a space nor a colon. Other
# lines (including those that float() / int() would still accept, such as "+5" or "1e4")
# send the file to the per-line checks. On these tokens pyarrow's string -> float64 / int64
# casts give float() / int() exactly (decimal rounded to the nearest double; an int64
# overflow raises and also sends the file to the per-line checks).
_ZIGBEE_LINE = (r"^(?P<t_ms>-?[0-9]+(?:\.[0-9]+)?) (?P<seq>-?[0-9]+) (?P<n>[0-9]+) "
                r"(?P<pairs>[^ :]+:-?[0-9]+(?: [^ :]+:-?[0-9]+)*)$")


def _zigbee_plain(raw: RawFile, anchors: set[str]) -> pd.DataFrame | None:
    """The rss rows of a clean zigbee.log, read in bulk by pyarrow (the same values as the
    per-line path); None when any line is not a _ZIGBEE_LINE or would be refused by the
    per-line checks (n against the pairs, unknown or repeated anchor, time going backwards)."""
    if raw.plain is None:
        return None
    lines = _plain_lines(raw)
    heads = pc.extract_regex(lines, _ZIGBEE_LINE)
    if heads.null_count:
        return None
    pairs = pc.split_pattern(heads.field("pairs"), " ")
    halves = pc.split_pattern(pairs.flatten(), ":")
    known = pa.array(sorted(anchors), type=pa.string())
    codes = pc.index_in(pc.list_element(halves, 0), value_set=known)
    try:
        t_ms, seq, n, rss = (pc.cast(column, kind).to_numpy() for column, kind in (
            (heads.field("t_ms"), pa.float64()), (heads.field("seq"), pa.int64()), (heads.field("n"), pa.int64()),
            (pc.list_element(halves, 1), pa.int64())))
    except pa.ArrowInvalid:
        return None
    pairs_per_line = pc.list_value_length(pairs).to_numpy().astype(np.int64)
    if codes.null_count or not (np.array_equal(n, pairs_per_line) and np.all(np.isfinite(t_ms))
                                and in_order(t_ms, strict=False)):
        return None
    line_of_pair = np.repeat(np.arange(len(lines)), pairs_per_line)
    if np.bincount(line_of_pair * len(known) + codes.to_numpy()).max() > 1:     # an anchor twice on one line
        return None
    return pd.DataFrame({"t": np.repeat(t_ms / 1000.0, pairs_per_line), "seq": seq[line_of_pair],
                         "anchor_id": pd.array(pc.list_element(halves, 0), dtype="str"),
                         "rss_dbm": rss.astype(float), "line": _plain_line_numbers(raw)[line_of_pair]})


def _zigbee_lines(raw: RawFile, techs: dict[str, str], quarantine: Quarantine) -> pd.DataFrame:
    """The rss rows of the usable lines, checked one by one (unusable ones quarantined)."""
    accepted, rejected = [], []
    for number, text, fields in iter_fields(raw):
        try:
            if len(fields) < 3:
                raise _LineError(f"expected 't_ms seq n anchor:rssi ...', found {len(fields)} fields")
            t_ms = _finite(fields[0], "t_ms")
            seq = _integer(fields[1], "seq")
            n = _integer(fields[2], "n")
            pairs = fields[3:]
            if n != len(pairs):
                raise _LineError(f"n = {n} but {len(pairs)} anchor:rssi pairs follow")
            line_rows, seen = [], set()
            for pair in pairs:
                anchor, sep, value = pair.partition(":")
                if not sep:
                    raise _LineError(f"pair {pair!r} is not anchor:rssi_dbm")
                _anchor(anchor, techs, "zigbee")
                if anchor in seen:
                    raise _LineError(f"anchor {anchor!r} appears twice")
                seen.add(anchor)
                rssi = _integer(value, f"rssi of {anchor}")
                line_rows.append((t_ms / 1000.0, seq, anchor, float(rssi), number))
        except _LineError as reason:
            rejected.append((number, text, str(reason)))
            continue
        accepted.append((number, text, t_ms, line_rows))
    kept = keep_in_time_order(raw.name, accepted, rejected, quarantine, strict=False)
    rows = [row for line_rows in kept for row in line_rows]
    return pd.DataFrame(rows, columns=["t", "seq", "anchor_id", "rss_dbm", "line"]) if rows else tables.empty("rss")


def imu_scales(raw: RawFile) -> tuple[float, float]:
    """accel_lsb_per_g and gyro_lsb_per_dps from the header; required to read the counts."""
    scales = []
    for key in ("accel_lsb_per_g", "gyro_lsb_per_dps"):
        value = header_value(raw, key)
        try:
            number = float(value) if value is not None else float("nan")
        except ValueError:
            number = float("nan")
        if not (math.isfinite(number) and number > 0):
            raise IngestError(f"{raw.path}: header must give '{key}=<positive number>' "
                              f"(found {value!r}); raw counts cannot be converted without it")
        scales.append(number)
    return scales[0], scales[1]


# A well-formed imu.log line (single spaces, plain decimal numbers): these are parsed in
# bulk; any other line goes through the per-line checks, which give the quarantine reason.
_REGULAR_IMU_LINE = re.compile(r"-?\d{1,15}(?:\.\d{1,9})?(?: (?:0|-?[1-9]\d{0,8})){4}")
_IMU_FIELDS = ("ax", "ay", "az", "gz")
MAX_COUNT = 2**31          # raw counts come from ADCs of at most 32 bits


def _imu_line(fields: list[str]) -> tuple[float, list[int]]:
    if len(fields) != 5:
        raise _LineError(f"expected 5 fields 't_ms ax ay az gz', found {len(fields)}")
    t_ms = _finite(fields[0], "t_ms")
    counts = [_integer(f, name) for f, name in zip(fields[1:], _IMU_FIELDS)]
    if any(abs(count) > MAX_COUNT for count in counts):
        raise _LineError(f"a count is beyond {MAX_COUNT:g} (no ADC gives that): {' '.join(fields[1:])[:60]}")
    return t_ms, counts


def parse_imu(raw: RawFile, campaign: Campaign, quarantine: Quarantine) -> pd.DataFrame:
    """imu.log: `t_ms ax ay az gz` raw counts; a = counts / lsb_per_g * g, w = counts / lsb_per_dps (deg/s -> rad/s).

    Time must increase strictly from one accepted line to the next (wsnloc.io.timeorder).
    """
    check_magic(raw, "-imu")
    accel_lsb, gyro_lsb = imu_scales(raw)
    plain = _imu_plain(raw)
    numbers, values, rejected = (*plain, []) if plain is not None else _imu_candidates(raw)
    accepted = longest_ordered(values[:, 0], strict=True)
    order_reasons = out_of_order_reasons(values[:, 0], accepted, strict=True)
    texts = dict(raw.lines) if order_reasons else {}
    rejected += [(int(numbers[i]), texts[int(numbers[i])], reason) for i, reason in order_reasons.items()]
    for number, text, reason in sorted(rejected):
        quarantine.add(raw.name, number, text, reason)
    if not accepted.any():
        return tables.empty("imu")
    g = campaign.spec["gravity_mps2"]
    if not accepted.all():
        numbers, values = numbers[accepted], values[accepted]
    t_ms, c = values[:, 0], values[:, 1:]
    return pd.DataFrame({
        "t": t_ms / 1000.0,
        "ax": c[:, 0] / accel_lsb * g,
        "ay": c[:, 1] / accel_lsb * g,
        "az": c[:, 2] / accel_lsb * g,
        "gz": np.deg2rad(c[:, 3] / gyro_lsb),
        "line": numbers.astype(np.int32),
    }, copy=False)    # the columns are new arrays: no consolidating copy


def _imu_plain(raw: RawFile) -> tuple[np.ndarray, np.ndarray] | None:
    """Line numbers and (t_ms, ax, ay, az, gz) of every line of a clean imu.log, read in
    bulk (the same values as the per-line path); None when any line would be refused by
    the per-line checks: field count, a token that is not a number / an integer, a count
    beyond MAX_COUNT, a t_ms that is not finite, or time that does not increase strictly."""
    columns = _plain_numbers(raw, {"t_ms": pa.float64(), **{name: pa.int64() for name in _IMU_FIELDS}})
    if columns is None:
        return None
    t_ms, counts = columns["t_ms"], [columns[name] for name in _IMU_FIELDS]
    beyond = any(np.any((count < -MAX_COUNT) | (count > MAX_COUNT)) for count in counts)
    if beyond or not in_order(t_ms, strict=True):
        return None
    values = np.empty((len(t_ms), 1 + len(counts)))      # filled column by column: no stacked copies
    values[:, 0] = t_ms
    for k, count in enumerate(counts, start=1):
        values[:, k] = count                             # int64 -> float64, exact (|count| <= MAX_COUNT)
    return _plain_line_numbers(raw), values


def _imu_candidates(raw: RawFile) -> tuple[np.ndarray, np.ndarray, list[tuple[int, str, str]]]:
    """Line numbers and (t_ms, ax, ay, az, gz) of the lines that parse, in file order, and
    the (line, text, reason) of those that do not (time order is checked afterwards).

    Regular lines are converted in bulk by numpy; the same numbers as float() / int() line
    by line, since both round each decimal string to the nearest double.
    """
    regular = [(number, text) for number, text in raw.lines if _REGULAR_IMU_LINE.fullmatch(text)]
    numbers = np.array([number for number, _ in regular], dtype=np.int64)
    values = np.fromstring(" ".join(text for _, text in regular), dtype=float, sep=" ").reshape(-1, 5)
    if len(regular) == len(raw.lines):
        return numbers, values, []
    regular_numbers = set(numbers.tolist())
    other_numbers, other_values, rejected = [], [], []
    for number, text in raw.lines:
        if number in regular_numbers:
            continue
        try:
            t_ms, counts = _imu_line(text.split())
        except _LineError as reason:
            rejected.append((number, text, str(reason)))
            continue
        other_numbers.append(number)
        other_values.append([t_ms, *counts])
    numbers = np.concatenate([numbers, np.array(other_numbers, dtype=np.int64)])
    values = np.vstack([values, np.array(other_values, dtype=float).reshape(-1, 5)])
    order = np.argsort(numbers, kind="stable")
    return numbers[order], values[order], rejected


def parse_truth(raw: RawFile, campaign: Campaign, quarantine: Quarantine) -> pd.DataFrame:
    """truth.log: `t_ms rail_m` (or `path_m`); (x, y) from the campaign's path at that arc length,
    and the height z where the path has a height profile (a 3-D scenario, Campaign.for_scenario)."""
    check_magic(raw, "-truth")
    length = campaign.path.length
    frame = _truth_plain(raw, length)
    if frame is None:
        frame = _truth_lines(raw, length, quarantine)
    if frame is None:
        return tables.empty("truth")
    pose = campaign.path.evaluate(frame["s"].to_numpy())
    frame["x"], frame["y"] = pose["x"], pose["y"]
    if "z" in pose:
        frame["z"] = pose["z"]
    return frame


def _truth_plain(raw: RawFile, length: float) -> pd.DataFrame | None:
    """(t, s, line) of every line of a clean truth.log, read in bulk (the same values as
    the per-line path); None when any line would be refused by the per-line checks."""
    columns = _plain_numbers(raw, {"t_ms": pa.float64(), "s": pa.float64()})
    if columns is None:
        return None
    t_ms, s = columns["t_ms"], columns["s"]
    if not (np.all((-TRUTH_TOLERANCE_M <= s) & (s <= length + TRUTH_TOLERANCE_M)) and in_order(t_ms, strict=True)):
        return None
    return pd.DataFrame({"t": t_ms / 1000.0, "s": s, "line": _plain_line_numbers(raw)})


def _truth_lines(raw: RawFile, length: float, quarantine: Quarantine) -> pd.DataFrame | None:
    """(t, s, line) of the usable lines, checked one by one (unusable ones quarantined);
    None when no line is usable."""
    accepted, rejected = [], []
    for number, text, fields in iter_fields(raw):
        try:
            if len(fields) != 2:
                raise _LineError(f"expected 2 fields 't_ms path position', found {len(fields)}")
            t_ms = _finite(fields[0], "t_ms")
            s = _finite(fields[1], "rail_m")
            if not -TRUTH_TOLERANCE_M <= s <= length + TRUTH_TOLERANCE_M:
                raise _LineError(f"rail_m = {s:g} is outside the path [0, {length:.2f}] m")
        except _LineError as reason:
            rejected.append((number, text, str(reason)))
            continue
        accepted.append((number, text, t_ms, (t_ms / 1000.0, s, number)))
    rows = keep_in_time_order(raw.name, accepted, rejected, quarantine, strict=True)
    return pd.DataFrame(rows, columns=["t", "s", "line"]) if rows else None


def ingest_run(run_dir: str | Path, campaign: Campaign) -> tuple[dict[str, pd.DataFrame], dict]:
    """Parse the four logs of one run directory.

    Returns the tables (ranges, rss, imu, truth, anchors, quarantine; tdoa from an optional
    tdoa.csv / tdoa.parquet beside the logs, generic format and rules) and an inventory:
    per file its SHA-256, line count and quarantined count. A missing file raises
    IngestError naming it.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise IngestError(f"{run_dir}: not a directory")
    quarantine = Quarantine()
    raws = {name: read_raw(run_dir / name, quarantine) for name in FILES}
    tdoa_path = generic.find(run_dir, "tdoa")        # optional: one-way UWB TDOA (generic format, sim.tdoa)
    tdoa = generic.tdoa_beside(tdoa_path, campaign.anchors, campaign.source) if tdoa_path is not None else None
    result = {
        "tdoa": tdoa[0] if tdoa is not None else tables.empty("tdoa"),
        "ranges": parse_uwb(raws["uwb.log"], campaign, quarantine),
        "rss": parse_zigbee(raws["zigbee.log"], campaign, quarantine),
        "imu": parse_imu(raws["imu.log"], campaign, quarantine),
        "truth": parse_truth(raws["truth.log"], campaign, quarantine),
        "anchors": campaign.anchors[["anchor_id", "tech", "x", "y", "z"]].copy(),
        "quarantine": quarantine.frame(),
    }
    q = result["quarantine"]
    inventory = {
        name: {"sha256": raw.sha256, "lines": raw.n_lines, "data_lines": raw.n_records,
               "quarantined": int((q["file"] == name).sum())}
        for name, raw in raws.items()
    }
    if tdoa is not None:
        rows = pd.DataFrame(tdoa[1], columns=["file", "line", "text", "reason"]).astype(q.dtypes.to_dict())
        result["quarantine"] = pd.concat([q, rows], ignore_index=True) if len(rows) else q
        inventory[tdoa_path.name] = tdoa[2]
    return result, inventory
