"""Reading raw text logs line by line, and the quarantine of unusable lines."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import pandas as pd

from wsnloc.errors import IngestError


@dataclass
class Quarantine:
    """Lines that could not be used: (file, line number, text, reason). Never dropped silently."""

    rows: list[tuple[str, int, str, str]] = field(default_factory=list)

    def add(self, file: str, line: int, text: str, reason: str) -> None:
        self.rows.append((file, line, text[:500], reason))

    def frame(self) -> pd.DataFrame:
        frame = pd.DataFrame(self.rows, columns=["file", "line", "text", "reason"])
        return frame.astype({"file": str, "line": "int32", "text": str, "reason": str})


@dataclass
class RawFile:
    """A raw log read whole: its header comments and its data lines with 1-based numbers."""

    path: Path
    header: list[str]
    lines: list[tuple[int, str]]
    sha256: str
    n_lines: int
    n_records: int      # non-blank, non-comment lines, usable or not

    @property
    def name(self) -> str:
        return self.path.name


def read_raw(path: str | Path, quarantine: Quarantine) -> RawFile:
    """Read an ASCII log. '#' lines before the first data line form the header.

    Trailing whitespace and CR are stripped; blank lines are skipped. Bytes that are not
    ASCII make that line unusable (quarantined). A missing or unreadable file raises
    IngestError naming the path.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise IngestError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    texts = _decode_lines(data, path.name, quarantine)
    header: list[str] = []
    lines: list[tuple[int, str]] = []
    n_records = 0
    for number, text in enumerate(texts, start=1):
        if text is None:                    # not ASCII: already quarantined
            n_records += 1
        elif text and text[0] != "#":
            n_records += 1
            lines.append((number, text))
        elif text and not lines:
            header.append(text)
    return RawFile(path, header, lines, hashlib.sha256(data).hexdigest(), len(texts), n_records)


def _decode_lines(data: bytes, name: str, quarantine: Quarantine) -> list[str | None]:
    """The file's lines, right-stripped; None for a line that is not ASCII (quarantined here)."""
    if data.isascii():                      # the usual case: decode the whole file at once
        texts = data.decode("ascii").split("\n")
        if texts[-1] == "":
            texts.pop()
        return [text.rstrip() for text in texts]
    raw_lines = data.split(b"\n")
    if raw_lines[-1] == b"":
        raw_lines.pop()
    texts: list[str | None] = []
    for number, raw in enumerate(raw_lines, start=1):
        try:
            texts.append(raw.decode("ascii").rstrip())
        except UnicodeDecodeError:
            quarantine.add(name, number, raw.decode("ascii", "replace").rstrip(), "not ASCII text")
            texts.append(None)
    return texts


def header_value(raw: RawFile, key: str) -> str | None:
    """Value of `key=value` in the header comments, or None."""
    for line in raw.header:
        for token in line.lstrip("#").split():
            if token.startswith(key + "="):
                return token.split("=", 1)[1]
    return None


KINDS = ("-uwb", "-zigbee", "-imu", "-truth", "-listener")


def check_magic(raw: RawFile, expected_kind: str) -> None:
    """The first header line names the log kind ('# newcom-uwb v1'); another kind is an error.

    A file without a format line is accepted (hand-made logs); the campaign prefix may
    differ (a Cricket run's imu.log says 'cricket-imu'); a header naming another kind of
    log is refused: it is most likely the wrong file.
    """
    if not raw.header:
        return
    first = raw.header[0].lstrip("#").strip()
    name = first.split()[0] if first.split() else ""
    if name.endswith(KINDS) and not name.endswith(expected_kind):
        raise IngestError(f"{raw.path}:1: expected a '*{expected_kind}' log, the header says '{first}'")


def iter_fields(raw: RawFile) -> Iterator[tuple[int, str, list[str]]]:
    """(line number, text, whitespace-separated fields) for each data line."""
    for number, text in raw.lines:
        yield number, text, text.split()
