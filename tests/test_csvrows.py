"""wsnloc.io.csvrows: files split at once give the rows the row-by-row reading gives."""

import numpy as np
import pytest

from wsnloc.io.csvrows import _clean_rows, _row_by_row, read_csv_rows

CLEAN = {"lf": b"t,anchor_id,range_m\n0.1,A1,2.5\n0.2,A2, 3.75 \n0.3,,4\n",
         "crlf": b"t,anchor_id,range_m\r\n0.1,A1,2.5\r\n0.2,A2,3.75\r\n"}
# each read row by row: a quote, a blank line, a line cut short, a wrong field count, bytes
# that are not UTF-8, carriage returns that do not end every line, a single column
DAMAGED = {"quote": b'a,b\n"1,5",2\n3,4\n', "blank": b"a,b\n1,2\n\n3,4\n", "spaces": b"a,b\n1,2\n  \n3,4\n",
           "cut": b"a,b\n1,2\n3,4", "fields": b"a,b\n1,2,3\n4,5\n", "bytes": b"a,b\n\xff,2\n3,4\n",
           "cr_some": b"a,b\r\n1,2\n3,4\r\n", "cr_twice": b"a,b\r\n1,2\r\r\n3,4\r\n", "cr_inside": b"a,b\n1,\r2\r\n",
           "one_column": b"a\n1\n2\n"}


def _lines(data: bytes) -> tuple[list[bytes], bool]:
    raw = data.split(b"\n")
    ended = raw[-1] == b""
    return (raw[:-1] if ended else raw), ended


def _same(a, b) -> bool:
    return (a.frame.equals(b.frame) and list(a.frame.dtypes) == list(b.frame.dtypes)
            and list(a.frame.columns) == list(b.frame.columns) and np.array_equal(a.lines, b.lines)
            and a.lines.dtype == b.lines.dtype and (a.refused, a.n_lines, a.n_records) == (b.refused, b.n_lines, b.n_records))


@pytest.mark.parametrize("name", sorted(CLEAN))
def test_clean_file_split_at_once_as_row_by_row(tmp_path, name):
    path = tmp_path / "ranges.csv"
    path.write_bytes(CLEAN[name])
    raw, ended = _lines(CLEAN[name])
    assert _clean_rows(raw, ended, 3) is not None
    header = ["t", "anchor_id", "range_m"]
    read = read_csv_rows(path)
    assert _same(read, _row_by_row(raw, ended, header))
    assert read.frame["range_m"].tolist()[1] == (" 3.75 " if name == "lf" else "3.75")


@pytest.mark.parametrize("name", sorted(DAMAGED))
def test_damaged_file_is_read_row_by_row(tmp_path, name):
    raw, ended = _lines(DAMAGED[name])
    header = raw[0].decode().rstrip("\r").split(",")
    assert _clean_rows(raw, ended, len(header)) is None
    path = tmp_path / "t.csv"
    path.write_bytes(DAMAGED[name])
    assert _same(read_csv_rows(path), _row_by_row(raw, ended, header))
