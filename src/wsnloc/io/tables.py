"""Canonical processed tables: explicit pyarrow schemas with SI units in the metadata.

Every stage after ingest reads only these tables, whatever the raw format was.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq


def _field(name: str, kind: pa.DataType, unit: str, description: str, nullable: bool = False,
           optional: bool = False) -> pa.Field:
    """A column with its unit; `nullable` where a value may be missing (NaN: no estimate);
    `optional` where a frame may lack the whole column (3-D values of planar data): the table
    is then written without it (to_arrow), so planar tables stay as they were."""
    metadata = {"unit": unit, "description": description, **({"optional": "1"} if optional else {})}
    return pa.field(name, kind, nullable=nullable or optional, metadata=metadata)


def _optional(field: pa.Field) -> bool:
    return (field.metadata or {}).get(b"optional") == b"1"


_LINE = _field("line", pa.int32(), "1", "line number in the raw file (1-based), for traceability")

_IMU = [   # accelerometer and z gyro in SI units, body frame (x forward, y left, z up)
    _field("ax", pa.float64(), "m/s^2", "specific force, body x (forward)"),
    _field("ay", pa.float64(), "m/s^2", "specific force, body y (left)"),
    _field("az", pa.float64(), "m/s^2", "specific force, body z (up)"),
    _field("gz", pa.float64(), "rad/s", "angular rate about body z"),
]

_ESTIMATE = [   # position estimate and its error, shared by the estimate tables
    _field("x", pa.float64(), "m", "estimated east coordinate (NaN: no fix)", nullable=True),
    _field("y", pa.float64(), "m", "estimated north coordinate (NaN: no fix)", nullable=True),
    _field("true_x", pa.float64(), "m", "truth at t", nullable=True),
    _field("true_y", pa.float64(), "m", "truth at t", nullable=True),
    _field("error_m", pa.float64(), "m", "Euclidean position error", nullable=True),
    _field("z", pa.float64(), "m", "estimated height (3-D state only)", optional=True),
    _field("true_z", pa.float64(), "m", "true height at t (truth with z only)", optional=True),
    _field("error_3d_m", pa.float64(), "m", "3-D position error (estimate and truth with z only)", optional=True),
]

_COVARIANCE = [   # position block of the estimator's state covariance (NaN where it has none)
    _field("p_xx", pa.float64(), "m^2", "variance of x", nullable=True),
    _field("p_xy", pa.float64(), "m^2", "covariance of x and y", nullable=True),
    _field("p_yy", pa.float64(), "m^2", "variance of y", nullable=True),
    _field("n_meas", pa.float64(), "1", "measurements in the update at t (NaN: not a filter)", nullable=True),
    _field("nis", pa.float64(), "1", "normalised innovation squared of that update", nullable=True),
]
_RUN = _field("run", pa.string(), "", "run name")
_EPOCH_T = _field("t", pa.float64(), "s", "estimate time (end of the estimation period)")

SCHEMAS: dict[str, pa.Schema] = {
    "ranges": pa.schema([
        _field("t", pa.float64(), "s", "receive time on the logger clock"),
        _field("anchor_id", pa.string(), "", "anchor identifier from the campaign file"),
        _field("range_m", pa.float64(), "m", "measured distance (c * two-way ToF / 2, or ultrasound)"),
        _field("status", pa.int32(), "1", "device status, 0 = valid; other values flag a meaningless range"),
        _LINE,
    ]),
    "tdoa": pa.schema([
        _field("t", pa.float64(), "s", "time of the tag's transmission (or of the paired ranges)"),
        _field("anchor_id", pa.string(), "", "anchor identifier"),
        _field("ref_anchor_id", pa.string(), "", "reference anchor of the pair"),
        _field("tdoa_m", pa.float64(), "m", "range difference d(anchor) - d(ref): c * (arrival at anchor - "
               "arrival at ref)"),
        _LINE,
    ]),
    "rss": pa.schema([
        _field("t", pa.float64(), "s", "receive time on the logger clock"),
        _field("seq", pa.int32(), "1", "broadcast sequence counter (-1 when the format has none)"),
        _field("anchor_id", pa.string(), "", "anchor identifier from the campaign file"),
        _field("rss_dbm", pa.float64(), "dBm", "received signal strength"),
        _LINE,
    ]),
    "imu": pa.schema([
        _field("t", pa.float64(), "s", "sample time on the sensor clock"),
        *_IMU,
        _LINE,
    ]),
    "imu_5hz": pa.schema([
        _field("t", pa.float64(), "s", "sample time of the resampled uniform grid (low-pass filtered values)"),
        *_IMU,
        _field("in_gap", pa.bool_(), "", "true where the raw stream had a hole longer than max_gap_s"),
    ]),
    "truth": pa.schema([
        _field("t", pa.float64(), "s", "time on the logger clock"),
        _field("s", pa.float64(), "m", "position along the campaign path (rail)"),
        _field("x", pa.float64(), "m", "east coordinate"),
        _field("y", pa.float64(), "m", "north coordinate"),
        _field("z", pa.float64(), "m", "height (a 3-D truth only; NaN: not given)", optional=True),
        _LINE,
    ]),
    "odometry": pa.schema([
        _field("t", pa.float64(), "s", "sample time on the logger clock"),
        _field("v_mps", pa.float64(), "m/s", "forward speed, body frame (negative: reversing)"),
        _field("yaw_rate_rps", pa.float64(), "rad/s", "yaw rate about the vertical, counter-clockwise positive"),
        _LINE,
    ]),
    "anchors": pa.schema([
        _field("anchor_id", pa.string(), "", "anchor identifier"),
        _field("tech", pa.string(), "", "technology: uwb, zigbee, cricket, ..."),
        _field("x", pa.float64(), "m", "east coordinate"),
        _field("y", pa.float64(), "m", "north coordinate"),
        _field("z", pa.float64(), "m", "height (NaN: 2-D campaign)", nullable=True),
    ]),
    "estimates": pa.schema([
        _RUN,
        _field("subset", pa.string(), "", "anchor subset"),
        _EPOCH_T,
        *_ESTIMATE,
        *_COVARIANCE,
    ]),
    "estimates_study": pa.schema([
        _field("cell", pa.string(), "", "study cell (its name under the study's estimators)"),
        _RUN,
        _field("subset", pa.string(), "", "anchor subset"),
        _EPOCH_T,
        *_ESTIMATE,
        *_COVARIANCE,
    ]),
    "estimates_paper_a": pa.schema([
        _RUN,
        _EPOCH_T,
        _field("table", pa.string(), "", "Table I (plain EKF) | Table II (motion detection)"),
        _field("row", pa.string(), "", "measurements | anchor subsets"),
        *_ESTIMATE,
        *_COVARIANCE,
    ]),
    "estimates_paper_c": pa.schema([
        _RUN,
        _EPOCH_T,
        _field("subset", pa.string(), "", "beacon subset"),
        _field("model", pa.string(), "", "motion model P | PV | PVA"),
        *_ESTIMATE,
        *_COVARIANCE,
    ]),
    "estimates_paper_d": pa.schema([
        _field("run", pa.string(), "", "run name"),
        _field("t", pa.float64(), "s", "epoch time (end of the estimation period)"),
        _field("localizer", pa.string(), "", "minmax | multilateration"),
        _field("technique", pa.string(), "", "narrowband | uwb | pmix | fmix"),
        _field("stage", pa.string(), "", "raw fix | velocity tracker | kalman filter"),
        *_ESTIMATE,
    ]),
    "estimates_paper_b": pa.schema([
        _field("run", pa.string(), "", "run name"),
        _field("t", pa.float64(), "s", "estimate time"),
        _field("method", pa.string(), "", "uwb | imu | sskf | kf"),
        *_ESTIMATE,
    ]),
    "quarantine": pa.schema([
        _field("file", pa.string(), "", "raw file the line came from"),
        _field("line", pa.int32(), "1", "line number in that file (1-based)"),
        _field("text", pa.string(), "", "the line as read (trailing whitespace removed)"),
        _field("reason", pa.string(), "", "why the line could not be used"),
    ]),
}

RAW_TABLES = ("ranges", "rss", "tdoa", "imu", "truth", "odometry", "anchors", "quarantine")


def empty(table: str) -> pd.DataFrame:
    """The table with no rows: its columns (without the optional ones) and types."""
    return pa.schema([f for f in SCHEMAS[table] if not _optional(f)]).empty_table().to_pandas()


def _column(frame: pd.DataFrame, field: pa.Field) -> pa.Array:
    """Column `field.name` of `frame` as `field.type`, converted as pa.Table.from_pandas does;
    raises KeyError when missing, ValueError when a non-nullable column holds NaN or None."""
    array = pa.array(frame[field.name], type=field.type, from_pandas=True)
    if not field.nullable and array.null_count:
        raise ValueError(f"column {field.name!r} is not nullable but holds {array.null_count} missing values")
    return array


def schema_for(table: str, frame: pd.DataFrame) -> pa.Schema:
    """The schema `frame` is written with: SCHEMAS[table] without the optional columns it lacks."""
    return pa.schema([f for f in SCHEMAS[table] if f.name in frame or not _optional(f)])


def to_arrow(table: str, frame: pd.DataFrame, extra_metadata: dict[str, str] | None = None) -> pa.Table:
    """Cast a DataFrame to the table's schema (columns in schema order); raises on mismatch.

    Column by column, on the calling thread: pa.Table.from_pandas would give the same table
    but copies the frame's columns first and starts a thread pool for every table.
    """
    schema = schema_for(table, frame)
    meta = {b"table": table.encode(), **{k.encode(): str(v).encode() for k, v in (extra_metadata or {}).items()}}
    return pa.Table.from_arrays([_column(frame, field) for field in schema], schema=schema).replace_schema_metadata(meta)


def write(table: str, frame: pd.DataFrame, path: str | Path, extra_metadata: dict[str, str] | None = None) -> None:
    """Write `frame` as the Parquet file of `table` (schema SCHEMAS[table], see to_arrow).

    LZ4 pages and dictionary encoding for the string columns only (anchor ids, names): about
    half the CPU of zstd with dictionaries on every column, and faster to read back, for
    files about a third larger. The table read back is the same either way.
    """
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    arrow = to_arrow(table, frame, extra_metadata)
    strings = [field.name for field in arrow.schema if pa.types.is_string(field.type)]
    pq.write_table(arrow, path, compression="lz4", use_dictionary=strings or False)


def read(path: str | Path, columns: list[str] | None = None) -> pd.DataFrame:
    """A written table as a DataFrame: all its columns, or only `columns` (in that order);
    KeyError when one of them is not in the file.

    One file, read and converted on the calling thread: pq.read_table and a threaded
    to_pandas give the same frame through the dataset machinery (path resolution,
    fragments) and thread pools, which cost more than reading a small table.
    """
    with pq.ParquetFile(path) as parquet:
        missing = sorted(set(columns or ()) - set(parquet.schema_arrow.names))
        if missing:
            raise KeyError(f"{path}: no column {', '.join(missing)}")
        return parquet.read(columns=columns, use_threads=False).to_pandas(use_threads=False)


def row_count(path: str | Path) -> int:
    """Number of rows of a written table, from its Parquet footer (no column is read)."""
    return pq.read_metadata(path).num_rows


def unit_of(path: str | Path, column: str) -> str:
    """The unit recorded for `column` in a written table's schema."""
    field = pq.read_schema(path).field(column)
    return (field.metadata or {}).get(b"unit", b"").decode()
