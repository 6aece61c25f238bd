"""Parser for what a Cricket listener prints (listener.log), plus the run's optional imu/truth logs.

Accepted line forms (one record per line):
  <host_ms>\t<payload>     host receive time in ms, then the listener output
  <payload>                no host prefix: time = TS x ts_unit_ms (campaign radio.cricket)
Payloads:
  v2 (listener mode 3):  VR=2.0,ID=01:25:61:61:0b:00:00:42,SP=B3,DB=155,DR=4518,TM=4890,TS=22528
                         keys in any order; DB, DR, TM, TS may be missing (RF only, no
                         range); TS is printed after DB and DR, so a line with a range but
                         no TS, or ending in a comma or a bare key, was cut short.
  older:                 $Cricket2,ver=3.0,id=45,dist=17,duration=1435,time=1195
                         $Cricket2,ver=3.0,space=MIT-0,id=45,dist=11,duration=1435
Range: DR (us) x speed of sound when DR is present, else DB (cm, or inches when the
campaign's units are imperial) / dist. On v2 lines DB and DR must agree (a disagreement
means a digit was lost); older firmware's `dist` units vary, so there only duration
counts. Beacons map through the campaign file: SP/space to `space_id`; a space id the
campaign does not list (real listeners print their own, e.g. SP=ship) falls back to
ID/id and `beacon_id` (hex bytes compared by value, so 1- and 2-digit bytes match).
Damage seen in real captures goes to the quarantine with a reason: lines cut short, two
records run together, empty values, absurd values, time out of order
(wsnloc.io.timeorder). Stray spaces are tolerated. RF-only records are valid but carry
no range; they are counted, not tabled. A run needs only listener.log: a listener capture
has no imu.log or truth.log, whose tables are then empty.

odometry.log (optional, the cart controller's wheel odometry; docs/raw-formats.md):
  # cricket-odometry v1
  <t_ms> <v_mmps> <yaw_mradps>   host ms, forward speed (mm/s, body frame, negative reversing)
                                 and yaw rate (mrad/s, counter-clockwise), integers
-> the odometry table (t s, v_mps, yaw_rate_rps). Quarantined: a wrong field count, a value
that is not a number (or not an integer), a speed or yaw rate beyond MAX_SPEED_MPS /
MAX_YAW_RATE_RPS, time not increasing.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io import newcom, tables
from wsnloc.io.rawlines import Quarantine, RawFile, check_magic, iter_fields, read_raw
from wsnloc.io.timeorder import keep_in_time_order
from wsnloc.sim.cricket import speed_of_sound

LISTENER = "listener.log"
OPTIONAL_FILES = ("imu.log", "truth.log", "odometry.log")
MAX_RANGE_M = 15.0            # Cricket ultrasound never reaches this far: longer is absurd
MAX_COUNTER = 2**32           # TS/TM are 32-bit listener counters
INCH_M = 0.0254
MAX_SPEED_MPS = 5.0           # an indoor cart: faster is a damaged line
MAX_YAW_RATE_RPS = 10.0       # ~570 deg/s: beyond any cart pivot
V2_KEYS = {"VR", "ID", "SP", "DB", "DR", "TM", "TS"}
OLD_KEYS = {"ver", "space", "id", "dist", "duration", "time"}
_HEX_BYTES = re.compile(r"^[0-9a-fA-F]{1,2}(:[0-9a-fA-F]{1,2}){7}$")


class _Bad(ValueError):
    pass


def canonical_id(text: str) -> str:
    """'1:25:61:61:b:0:0:42' -> '01:25:61:61:0b:00:00:42'."""
    if not _HEX_BYTES.match(text):
        raise _Bad(f"ID {text!r} is not 8 hex bytes")
    return ":".join(f"{int(b, 16):02x}" for b in text.split(":"))


def _fields(payload: str, allowed: set[str], separator: str = "=") -> dict[str, str]:
    out: dict[str, str] = {}
    parts = payload.split(",")
    for position, part in enumerate(parts):
        key, sep, value = part.partition(separator)
        key, value = key.strip(), value.strip()
        if not sep and position and position == len(parts) - 1:
            raise _Bad(f"line cut short (ends with ',{key}')" if key else "line cut short after a comma")
        if not sep:
            raise _Bad(f"field {part.strip()!r} is not KEY=value")
        if key not in allowed:
            if any(k in key or k in value for k in ("VR", "$Cricket")):
                raise _Bad("two records run together")
            raise _Bad(f"unknown key {key!r}")
        if key in out:
            raise _Bad(f"key {key} appears twice (two records run together?)")
        if value:                                      # empty value (SP=,DB=) = field missing
            out[key] = value
    return out


def _number(fields: dict, key: str, kind=float):
    if key not in fields:
        return None
    text = fields[key]
    try:
        value = kind(text)
    except ValueError:
        if "VR=" in text or "\t" in text:
            raise _Bad("two records run together") from None
        raise _Bad(f"{key}={text!r} is not a number") from None
    if isinstance(value, float) and not math.isfinite(value):
        raise _Bad(f"{key}={text!r} is not finite")
    return value


def parse_payload(payload: str) -> dict:
    """Normalise a v2 or older payload into {space, id, db, dr_us, ts}; raises _Bad."""
    payload = payload.strip()
    if payload.count("VR=") > 1 or payload.count("$Cricket") > 1:
        raise _Bad("two records run together")
    if payload.startswith("$Cricket2"):
        f = _fields(payload[len("$Cricket2"):].lstrip(","), OLD_KEYS)
        return {"space": f.get("space"), "id": f.get("id"), "db": _number(f, "dist"),
                "dr_us": _number(f, "duration"), "ts": _number(f, "time", int), "old": True}
    f = _fields(payload, V2_KEYS)
    if "TS" not in f and ("DB" in f or "DR" in f):
        raise _Bad("a range but no TS field: line cut short")
    if "VR" not in f:
        raise _Bad("no VR field: not a Cricket v2 record")
    for key in ("TS", "TM"):
        value = _number(f, key, int)
        if value is not None and not 0 <= value < MAX_COUNTER:
            raise _Bad(f"absurd counter {key}={value}")
    return {"space": f.get("SP"), "id": f.get("ID"), "db": _number(f, "DB"), "dr_us": _number(f, "DR"),
            "ts": _number(f, "TS", int), "old": False}


class _BeaconMap:
    def __init__(self, campaign: Campaign):
        anchors = campaign.anchors_of("cricket")
        self.by_space = dict(zip(anchors.get("space_id", pd.Series(dtype=str)).dropna(), anchors["anchor_id"]))
        ids = anchors.get("beacon_id", pd.Series(dtype=str))
        self.by_id = {canonical_id(i): a for i, a in zip(ids, anchors["anchor_id"]) if isinstance(i, str)}
        self.by_short_id = {str(int(i.split(":")[-1], 16)): a for i, a in self.by_id.items()}

    def resolve(self, record: dict) -> str:
        """The anchor of a record: by space id, else (unknown or missing space) by beacon id."""
        if record["space"] is not None:
            if record["space"] in self.by_space:
                return self.by_space[record["space"]]
            if not record["old"] and record["id"] is None:
                raise _Bad(f"unknown space id SP={record['space']!r} and no ID")
        if record["id"] is not None:
            key = record["id"].strip()
            if record["old"] and key.isdigit() and key in self.by_short_id:
                return self.by_short_id[key]
            if not record["old"] and canonical_id(key) in self.by_id:
                return self.by_id[canonical_id(key)]
            space = f"unknown space id SP={record['space']!r} and " if record["space"] is not None else ""
            raise _Bad(f"{space}unknown beacon id {key!r}")
        raise _Bad("no beacon: SP and ID missing or empty")


def parse_listener(raw: RawFile, campaign: Campaign, quarantine: Quarantine) -> tuple[pd.DataFrame, int]:
    """Ranges table from listener.log and the number of RF-only (no range) records.

    Range (m) = DR (us) * 1e-6 * c(T), c from the campaign's temperature, else DB x unit.
    """
    spec = campaign.section("radio", "cricket")
    c = speed_of_sound(spec["temperature_c"])
    db_unit_m = INCH_M if spec.get("units", "metric") == "imperial" else 0.01
    ts_unit_s = spec.get("ts_unit_ms", 1.0) / 1000.0
    beacons = _BeaconMap(campaign)
    accepted, rejected = [], []
    for number, text in raw.lines:
        try:
            host, tab, payload = text.partition("\t")
            if tab:
                try:
                    t = int(host.strip()) / 1000.0
                except ValueError:
                    raise _Bad(f"host time {host!r} is not an integer") from None
                if "\t" in payload:
                    raise _Bad("two records run together")
            else:
                payload = text
            record = parse_payload(payload)
            if not tab:
                if record["ts"] is None:
                    raise _Bad("no host time and no TS: no timestamp")
                t = record["ts"] * ts_unit_s
            anchor = beacons.resolve(record)
            if record["dr_us"] is not None:
                range_m = record["dr_us"] * 1e-6 * c
            elif record["db"] is not None:
                range_m = record["db"] * db_unit_m
            else:
                range_m = None
            if range_m is not None and not 0.0 < range_m <= MAX_RANGE_M:
                raise _Bad(f"absurd range {range_m:.2f} m")
            if record["dr_us"] is not None and record["db"] is not None and not record["old"]:
                db_m = record["db"] * db_unit_m
                if abs(db_m - range_m) > max(0.1, 0.05 * range_m):
                    raise _Bad(f"DB ({db_m:.2f} m) and DR ({range_m:.2f} m) disagree: line damaged")
        except _Bad as reason:
            rejected.append((number, text, str(reason)))
            continue
        accepted.append((number, text, t * 1000.0, (t, anchor, range_m, 0, number)))
    kept = keep_in_time_order(raw.name, accepted, rejected, quarantine, strict=False)
    rows = [row for row in kept if row[2] is not None]
    frame = pd.DataFrame(rows, columns=["t", "anchor_id", "range_m", "status", "line"]) if rows else tables.empty("ranges")
    return frame, len(kept) - len(rows)


def _odometry_line(fields: list[str]) -> tuple[float, float, float]:
    if len(fields) != 3:
        raise _Bad(f"expected 3 fields 't_ms v_mmps yaw_mradps', found {len(fields)}")
    t_ms = _number({"t_ms": fields[0]}, "t_ms")
    v, w = (_number({key: text}, key, int) / 1000.0 for key, text in zip(("v_mmps", "yaw_mradps"), fields[1:]))
    if abs(v) > MAX_SPEED_MPS:
        raise _Bad(f"speed {v:g} m/s beyond {MAX_SPEED_MPS:g} m/s")
    if abs(w) > MAX_YAW_RATE_RPS:
        raise _Bad(f"yaw rate {w:g} rad/s beyond {MAX_YAW_RATE_RPS:g} rad/s")
    return t_ms, v, w


def parse_odometry(raw: RawFile, quarantine: Quarantine) -> pd.DataFrame:
    """odometry.log: `t_ms v_mmps yaw_mradps` -> the odometry table (t s, v_mps m/s, yaw_rate_rps
    rad/s); time must increase strictly (wsnloc.io.timeorder)."""
    check_magic(raw, "-odometry")
    accepted, rejected = [], []
    for number, text, fields in iter_fields(raw):
        try:
            t_ms, v, w = _odometry_line(fields)
        except _Bad as reason:
            rejected.append((number, text, str(reason)))
            continue
        accepted.append((number, text, t_ms, (t_ms / 1000.0, v, w, number)))
    rows = keep_in_time_order(raw.name, accepted, rejected, quarantine, strict=True)
    return (pd.DataFrame(rows, columns=["t", "v_mps", "yaw_rate_rps", "line"]) if rows
            else tables.empty("odometry"))


def ingest_run(run_dir: str | Path, campaign: Campaign) -> tuple[dict[str, pd.DataFrame], dict]:
    """Parse listener.log (required) and imu.log, truth.log, odometry.log (when present) of one Cricket run."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise IngestError(f"{run_dir}: not a directory")
    quarantine = Quarantine()
    names = [LISTENER] + [name for name in OPTIONAL_FILES if (run_dir / name).is_file()]
    raws = {name: read_raw(run_dir / name, quarantine) for name in names}
    ranges, rf_only = parse_listener(raws[LISTENER], campaign, quarantine)
    result = {
        "ranges": ranges,
        "rss": tables.empty("rss"),
        "imu": newcom.parse_imu(raws["imu.log"], campaign, quarantine) if "imu.log" in raws else tables.empty("imu"),
        "truth": (newcom.parse_truth(raws["truth.log"], campaign, quarantine) if "truth.log" in raws
                  else tables.empty("truth")),
        "odometry": (parse_odometry(raws["odometry.log"], quarantine) if "odometry.log" in raws
                     else tables.empty("odometry")),
        "anchors": campaign.anchors[["anchor_id", "tech", "x", "y", "z"]].copy(),
        "quarantine": quarantine.frame(),
    }
    q = result["quarantine"]
    inventory = {name: {"sha256": raw.sha256, "lines": raw.n_lines, "data_lines": raw.n_records,
                        "quarantined": int((q["file"] == name).sum())} for name, raw in raws.items()}
    inventory[LISTENER]["rf_only"] = rf_only
    return result, inventory
