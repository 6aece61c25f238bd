"""Reading raw text logs line by line, and the quarantine of unusable lines."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np
import pandas as pd

from wsnloc.errors import IngestError


@dataclass
class Quarantine:
    """Lines that could not be used: (file, line number, text, reason). Never dropped silently."""

    rows: list[tuple[str, int, str, str]] = field(default_factory=list)

    def add(self, file: str, line: int, text: str, reason: str) -> None:
        self.rows.append((file, line, text[:500], reason))

    def frame(self) -> pd.DataFrame:
        """The rows as a table (file, line, text, reason): strings and int32 line numbers,
        each column built at its type (a frame of objects cast afterwards costs several times more)."""
        files, lines, texts, reasons = zip(*self.rows) if self.rows else ((), (), (), ())
        return pd.DataFrame({"file": pd.array(files, dtype="str"), "line": np.array(lines, dtype=np.int32),
                             "text": pd.array(texts, dtype="str"), "reason": pd.array(reasons, dtype="str")})


class RawFile:
    """A raw log read whole: its header comments and its data lines with 1-based numbers.

    `plain`: the file's data lines as bytes when they are plain (see `plain_body`), the
    first of them being line `first_line`, else None. `lines` may then be None: the
    (line number, text) list is only built when asked for, since the parsers' bulk paths
    read `plain` instead.
    """

    def __init__(self, path: Path, header: list[str], lines: list[tuple[int, str]] | None, sha256: str,
                 n_lines: int, n_records: int, plain: bytes | None = None, first_line: int = 1):
        self.path, self.header, self.sha256 = Path(path), header, sha256
        self.n_lines = n_lines
        self.n_records = n_records          # non-blank, non-comment lines, usable or not
        self.plain, self.first_line = plain, first_line
        self._lines = lines

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def lines(self) -> list[tuple[int, str]]:
        """(line number, text) of each data line, in file order."""
        if self._lines is None:
            texts = self.plain.decode("ascii").split("\n")
            if texts[-1] == "":
                texts.pop()
            self._lines = list(enumerate(texts, start=self.first_line))
        return self._lines


# Whitespace that str.rstrip() removes from an ASCII line, other than the space and "\n".
_OTHER_SPACE = (b"\t", b"\r", b"\x0b", b"\x0c", b"\x1c", b"\x1d", b"\x1e", b"\x1f")


def plain_body(body: bytes) -> bool:
    """Whether every line of `body` (an ASCII file from its first data line on) is a data
    line exactly as read_raw keeps it.

    That is: no blank line, no comment line, no whitespace at a line's end and no
    whitespace but spaces and line ends; the line texts are then the bytes between the
    newlines, and their count is the number of data lines.
    """
    return bool(body) and not (body.endswith(b" ") or any(space in body for space in _OTHER_SPACE)
                               or _blank_trailing_or_comment(body))


def _blank_trailing_or_comment(body: bytes) -> bool:
    """Whether `body` holds b"\n\n", b" \n" or b"\n#": a newline after a newline or a space,
    or before a '#'. One vectorised pass over the newlines' positions (bytes.__contains__
    with a two-byte pattern is several times slower on a 1 MB log)."""
    codes = np.frombuffer(body, dtype=np.uint8)
    ends = np.flatnonzero(codes == ord("\n"))
    before = codes[ends[ends > 0] - 1]
    after = codes[ends[ends < len(codes) - 1] + 1]
    return bool(np.any((before == ord("\n")) | (before == ord(" "))) or np.any(after == ord("#")))


def read_raw(path: str | Path, quarantine: Quarantine) -> RawFile:
    """Read an ASCII log. '#' lines before the first data line form the header.

    Trailing whitespace and CR are stripped; blank lines are skipped. Bytes that are not
    ASCII make that line unusable (quarantined). A missing or unreadable file raises
    IngestError naming the path. An ASCII file whose data lines are plain keeps them as
    bytes (RawFile.plain) for the parsers' bulk paths.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise IngestError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    return raw_from_bytes(path, data, quarantine)


def raw_from_bytes(path: str | Path, data: bytes, quarantine: Quarantine) -> RawFile:
    """read_raw of a log held in memory as bytes (`path` names it in the quarantine)."""
    path = Path(path)
    sha256 = hashlib.sha256(data).hexdigest()
    if data.isascii():
        header, start, first_line = _ascii_header(data)
        body = data[start:]
        if plain_body(body):
            n_records = body.count(b"\n") + (not body.endswith(b"\n"))
            return RawFile(path, header, None, sha256, first_line - 1 + n_records, n_records, body, first_line)
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
    return RawFile(path, header, lines, sha256, len(texts), n_records)


def _ascii_header(data: bytes) -> tuple[list[str], int, int]:
    """Header comments (right-stripped) before the first data line of an ASCII file, the
    byte offset of that line and its 1-based number (past the end: the file has none)."""
    header, start, number = [], 0, 1
    while start < len(data):
        end = data.find(b"\n", start)
        end = len(data) if end < 0 else end
        text = data[start:end].decode("ascii").rstrip()
        if text and text[0] != "#":
            break
        if text:
            header.append(text)
        start, number = end + 1, number + 1
    return header, start, number


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


KINDS = ("-uwb", "-zigbee", "-imu", "-truth", "-listener", "-odometry")


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
