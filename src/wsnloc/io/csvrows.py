"""Reading a CSV table row by row, so that a damaged row is refused alone, with its line.

A CSV file from another dataset may carry the same damage as a raw log: a row with too
many or too few fields, bytes that are not text, a last line cut off by a copy that
stopped mid-write. Such rows are returned as refused (line, text, reason) instead of
failing the whole file; only a file without a usable header line raises IngestError.
Line numbers are the file's own (header = line 1), blank lines are skipped.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc.errors import IngestError


@dataclass
class CsvRows:
    """The rows of a CSV file that have as many fields as its header, as text."""

    frame: pd.DataFrame            # one str column per header field
    lines: np.ndarray              # line number of each row of `frame`
    refused: list[tuple[int, str, str]]   # (line, text, reason) of the rows that could not be split
    n_lines: int                   # lines in the file, header and blank lines included
    n_records: int                 # non-blank data lines, usable or not


def _split(text: str) -> list[str]:
    """Fields of one CSV line; quoted fields only go through the csv module (slower)."""
    if '"' not in text:
        return text.split(",")
    return next(csv.reader([text]), [])


def read_csv_rows(path: Path) -> CsvRows:
    """Read `path` as CSV: header on line 1, then one row per line (see module docstring)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise IngestError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    raw_lines = data.split(b"\n")
    ends_with_newline = raw_lines[-1] == b""
    if ends_with_newline:
        raw_lines.pop()
    if not raw_lines or not raw_lines[0].strip():
        raise IngestError(f"{path}: empty file (line 1 must be the header naming the columns)")
    try:
        header = [name.strip() for name in _split(raw_lines[0].decode("utf-8").rstrip("\r"))]
    except UnicodeDecodeError:
        raise IngestError(f"{path}:1: the header is not UTF-8 text") from None
    repeated = sorted({name for name in header if header.count(name) > 1})
    if repeated:
        raise IngestError(f"{path}:1: column(s) {repeated} appear more than once in the header")
    columns = _clean_rows(raw_lines, ends_with_newline, len(header))
    if columns is not None:
        frame = pd.DataFrame(dict(zip(header, columns)), columns=header, dtype=str)
        count = len(raw_lines) - 1
        return CsvRows(frame, np.arange(2, count + 2, dtype=np.int64), [], len(raw_lines), count)
    return _row_by_row(raw_lines, ends_with_newline, header)


def _row_by_row(raw_lines: list[bytes], ends_with_newline: bool, header: list[str]) -> CsvRows:
    """The data lines (raw_lines[1:]) one at a time: each damaged line refused alone, with its line number."""
    rows, lines, refused, n_records = [], [], [], 0
    for number, raw in enumerate(raw_lines[1:], start=2):
        try:
            text = raw.decode("utf-8").rstrip("\r")
        except UnicodeDecodeError:
            n_records += 1
            refused.append((number, raw.decode("utf-8", "replace").rstrip(), "not UTF-8 text"))
            continue
        if not text.strip():
            continue
        n_records += 1
        if number == len(raw_lines) and not ends_with_newline:
            refused.append((number, text, "cut short: the file ends inside this line (no end of line)"))
            continue
        fields = _split(text)
        if len(fields) != len(header):
            refused.append((number, text, f"expected {len(header)} fields ({','.join(header)}), found {len(fields)}"))
            continue
        rows.append(fields)
        lines.append(number)
    frame = pd.DataFrame(rows, columns=header, dtype=str) if rows else pd.DataFrame(columns=header, dtype=str)
    return CsvRows(frame, np.array(lines, dtype=np.int64), refused, len(raw_lines), n_records)


def _clean_rows(raw_lines: list[bytes], ends_with_newline: bool, width: int) -> list[list[str]] | None:
    """The columns (one list of str per header field) of a file whose data lines are all usable
    as they are: UTF-8, no quote, no carriage return but one ending every line or none, none
    blank, each with `width` fields, the last one ended. Split at once: the rows _row_by_row
    gives (none refused) at a fraction of its CPU; None for any other file, read by _row_by_row."""
    data = raw_lines[1:]
    if width < 2 or not data or not ends_with_newline:
        return None
    try:
        text = b"\n".join(data).decode("utf-8")
    except UnicodeDecodeError:
        return None
    if "\r" in text:        # Windows line ends: one carriage return ending each line, what rstrip("\r") removes
        if text.count("\r") != len(data) or text.count("\r\n") != len(data) - 1 or not text.endswith("\r"):
            return None
        text = text.replace("\r", "")
    if '"' in text:
        return None
    lines = text.split("\n")
    if any(line.count(",") != width - 1 for line in lines):     # also every blank line (no comma)
        return None
    fields = ",".join(lines).split(",")
    return [fields[k::width] for k in range(width)]

