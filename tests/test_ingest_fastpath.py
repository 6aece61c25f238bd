"""Issue 18: the bulk (fast) paths of the raw-log parsers give exactly the per-line path's
tables, quarantine and counts, on clean simulated logs of every format and on damaged ones.

The per-line path is forced by handing a parser the same RawFile without its plain body.
"""

import itertools

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io import cricket, newcom, tables
from wsnloc.io.limits import QuarantineLimits, check_quarantine_limits, within_limits
from wsnloc.io.rawlines import Quarantine, RawFile, plain_body, read_raw
from wsnloc.sim.cricket import simulate_run as simulate_cricket
from wsnloc.sim.seeding import run_seed_sequence

from conftest import ROOT

PARSERS = {"uwb.log": newcom.parse_uwb, "zigbee.log": newcom.parse_zigbee, "imu.log": newcom.parse_imu,
           "truth.log": newcom.parse_truth}
DAMAGE = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _per_line(raw: RawFile) -> RawFile:
    """The same file without its plain body: the parsers take their per-line path."""
    return RawFile(raw.path, raw.header, list(raw.lines), raw.sha256, raw.n_lines, raw.n_records)


def _both_paths(path, campaign):
    """(table, quarantine rows) of the file through read_raw as is, then per line."""
    results = []
    for force_per_line in (False, True):
        quarantine = Quarantine()
        raw = read_raw(path, quarantine)
        table = PARSERS[path.name](_per_line(raw) if force_per_line else raw, campaign, quarantine)
        results.append((table, quarantine.rows))
    return results


def _reference(path):
    """(lines, data lines, (number, text) of the ASCII data lines, header) of a log as read_raw
    defines them, line by line: text right-stripped, blank and '#' lines skipped, a line
    that is not ASCII counted as a data line (it is quarantined), the header made of the
    '#' lines before the first data line."""
    texts = path.read_bytes().split(b"\n")
    if texts[-1] == b"":
        texts.pop()
    records = [not text.isascii() or bool(text.rstrip() and not text.startswith(b"#")) for text in texts]
    lines = [(number, text.decode().rstrip()) for number, (text, record) in enumerate(zip(texts, records), start=1)
             if record and text.isascii()]
    before_data = texts[: lines[0][0] - 1] if lines else texts
    header = [text.decode().rstrip() for text in before_data if text.isascii() and text.startswith(b"#")]
    return len(texts), sum(records), lines, header


@pytest.fixture(scope="module")
def cricket_run(tmp_path_factory):
    campaign = Campaign.load(ROOT / "config" / "campaigns" / "cricket.yaml")
    out = tmp_path_factory.mktemp("sim") / "run-01"
    return campaign, simulate_cricket(campaign, "speed_40", run_seed_sequence(7, "cricket", "speed_40", 1), out)


@pytest.mark.parametrize("name", list(PARSERS))
def test_clean_newcom_logs_take_the_bulk_path_with_the_per_line_result(simulated_run, campaign, name):
    raw = read_raw(simulated_run / name, Quarantine())
    assert raw.plain is not None and raw.lines[0][0] == raw.first_line
    (fast, fast_bad), (slow, slow_bad) = _both_paths(simulated_run / name, campaign)
    assert len(fast) > 0 and fast_bad == slow_bad == []
    pd.testing.assert_frame_equal(fast, slow, check_exact=True)


def test_clean_logs_are_all_read_in_bulk(simulated_run, campaign):
    """Guards the speed: no clean log falls back to the per-line path."""
    raws = {name: read_raw(simulated_run / name, Quarantine()) for name in PARSERS}
    zigbee = set(campaign.anchors_of("zigbee")["anchor_id"])
    uwb = set(campaign.anchors_of("uwb")["anchor_id"])
    assert newcom._uwb_plain(raws["uwb.log"], campaign.spec["speed_of_light_mps"], uwb) is not None
    assert newcom._imu_plain(raws["imu.log"]) is not None
    assert newcom._truth_plain(raws["truth.log"], campaign.path.length) is not None
    assert newcom._zigbee_plain(raws["zigbee.log"], zigbee) is not None


@pytest.mark.parametrize("name", ["imu.log", "truth.log"])
def test_clean_cricket_logs_take_the_bulk_path_with_the_per_line_result(cricket_run, name):
    campaign, run = cricket_run
    assert read_raw(run / name, Quarantine()).plain is not None
    (fast, fast_bad), (slow, slow_bad) = _both_paths(run / name, campaign)
    assert len(fast) > 0 and fast_bad == slow_bad == []
    pd.testing.assert_frame_equal(fast, slow, check_exact=True)


def test_whole_run_inventory_counts_match_the_line_by_line_definition(simulated_run, cricket_run, campaign):
    _, inventory = newcom.ingest_run(simulated_run, campaign)
    for name in PARSERS:
        assert (inventory[name]["lines"], inventory[name]["data_lines"]) == _reference(simulated_run / name)[:2]
    cricket_campaign, run = cricket_run
    _, inventory = cricket.ingest_run(run, cricket_campaign)
    for name, counts in inventory.items():
        assert (counts["lines"], counts["data_lines"]) == _reference(run / name)[:2]


# --- damaged logs: whatever the damage, both paths agree --------------------------------------

LINE_DAMAGE = [
    lambda s: "",                               # blank line
    lambda s: "# a comment",
    lambda s: s + " ",                          # trailing space
    lambda s: s + "\r",
    lambda s: s.replace(" ", "  ", 1),
    lambda s: s.replace(" ", "\t", 1),
    lambda s: " " + s,
    lambda s: s.rsplit(" ", 1)[0],              # a field missing
    lambda s: s + " 7",                         # a field too many
    lambda s: s.replace(" ", " nan ", 1)[: len(s) + 4],
    lambda s: "inf" + "".join(s.partition(" ")[1:]),   # first field replaced (a line without spaces: "inf")
    lambda s: "1e4" + "".join(s.partition(" ")[1:]),
    lambda s: s.replace(" ", " +", 1),
    lambda s: s.replace("0", "0_0", 1),
    lambda s: s.replace(" ", " 2147483649 ", 1).rsplit(" ", 1)[0],
    lambda s: s.replace(" ", " 9223372036854775808 ", 1).rsplit(" ", 1)[0],
    lambda s: s.replace(" ", " -0 ", 1).rsplit(" ", 1)[0],
    lambda s: s.replace(" ", " 1.5 ", 1).rsplit(" ", 1)[0],
    lambda s: s.replace(" ", " 1. ", 1).rsplit(" ", 1)[0],
    lambda s: "-" + s,
    lambda s: "1" * 400 + "".join(s.partition(" ")[1:]),    # t_ms overflows to inf (float() too)
    lambda s: s.replace(":", "::", 1),
    lambda s: s.replace(":", " ", 1),
    lambda s: s.replace(":", " ", 1).replace(" Z02:", ":Z02:", 1),     # a pair without its colon
    lambda s: s.replace("Z02:", "Z01:", 1),
    lambda s: s.replace("Z01:", "Q01:", 1),
    lambda s: s.replace(" U0", " Z0", 1),       # an anchor of another technology
    lambda s: s + "\u00e9",                     # not ASCII
    lambda s: s[: len(s) // 2],                 # cut short
    lambda s: s + "\n",                         # then a blank line
]


def _damage(lines: list[str], i: int, kind: int, j: int) -> None:
    """Damage line i in place: LINE_DAMAGE[kind], else repeat it, else swap it with line j."""
    if kind == len(LINE_DAMAGE):
        lines.insert(i, lines[i])                                   # a line repeated
    elif kind == len(LINE_DAMAGE) + 1:
        lines[i], lines[j] = lines[j], lines[i]                     # time out of order
    else:
        lines[i] = LINE_DAMAGE[kind](lines[i])


@st.composite
def damaged_log(draw, good: list[str]):
    """`good` with lines damaged at random (the last line maybe without its line end)."""
    lines = list(good)
    for _ in range(draw(st.integers(0, 3))):
        index = st.integers(0, len(lines) - 1)
        _damage(lines, draw(index), draw(st.integers(0, len(LINE_DAMAGE) + 1)), draw(index))
    return "".join(line + "\n" for line in lines)[: None if draw(st.booleans()) else -1]


def _good_lines(name, n=12):
    t = 10000 + 2 * np.arange(n)
    if name == "imu.log":
        return [f"{t[k]}.{k:03d} {k - 5} 3 1022 {-k}" for k in range(n)]
    if name == "truth.log":
        return [f"{t[k]} {k * 0.01:.2f}" for k in range(n)]
    if name == "uwb.log":
        return [f"{t[k]} U0{k % 4 + 1} {12000 + 999 * k} {k % 2 * 7}" for k in range(n)]
    return [f"{t[k]} {k} 2 Z01:-{50 + k} Z02:-{60 + k}" for k in range(n)]


HEADERS = {"uwb.log": "# newcom-uwb v1\n", "imu.log": "# newcom-imu v1\n# accel_lsb_per_g=1024 gyro_lsb_per_dps=131.072\n",
           "truth.log": "# newcom-truth v1\n", "zigbee.log": "# newcom-zigbee v1\n"}


def _check_both_paths(campaign, folder, name, body):
    (folder / name).write_bytes((HEADERS[name] + body).encode("utf-8"))
    (fast, fast_bad), (slow, slow_bad) = _both_paths(folder / name, campaign)
    assert fast_bad == slow_bad
    pd.testing.assert_frame_equal(fast, slow, check_exact=True)
    raw = read_raw(folder / name, Quarantine())
    assert (raw.n_lines, raw.n_records, raw.lines, raw.header) == _reference(folder / name)
    return fast_bad


@pytest.mark.parametrize("name", list(HEADERS))
@pytest.mark.parametrize("kind", range(len(LINE_DAMAGE) + 2))
@pytest.mark.parametrize("where", ["inside", "last line, no line end"])
def test_each_damage_gives_the_same_result_on_both_paths(campaign, tmp_path, name, kind, where):
    lines = _good_lines(name)
    _damage(lines, 3 if where == "inside" else len(lines) - 1, kind, 8)
    body = "".join(line + "\n" for line in lines)
    _check_both_paths(campaign, tmp_path, name, body if where == "inside" else body[:-1])


@pytest.mark.parametrize("name", list(HEADERS))
@DAMAGE
@given(data=st.data())
def test_random_damage_gives_the_same_result_on_both_paths(campaign, tmp_path, name, data):
    _check_both_paths(campaign, tmp_path, name, data.draw(damaged_log(_good_lines(name))))


@pytest.mark.parametrize("beyond_m", [-0.5, 0.5])
def test_truth_beyond_the_path_gives_the_same_result_on_both_paths(campaign, tmp_path, beyond_m):
    lines = _good_lines("truth.log")
    s = (0.0 if beyond_m < 0 else campaign.path.length) + beyond_m
    lines[3] = f"{lines[3].split()[0]} {s:.2f}"
    bad = _check_both_paths(campaign, tmp_path, "truth.log", "".join(line + "\n" for line in lines))
    assert [line for _, line, _, _ in bad] == [5]


@pytest.mark.parametrize("before", ["\n", "   \n", "# a note  \r\n", "\n# a note\n\n"])
def test_blank_and_comment_lines_before_the_data_are_read_as_line_by_line(campaign, tmp_path, before):
    body = before + "".join(line + "\n" for line in _good_lines("imu.log"))
    _check_both_paths(campaign, tmp_path, "imu.log", body)
    raw = read_raw(tmp_path / "imu.log", Quarantine())
    assert raw.plain is not None and raw.header[-1] != ""


# --- the helpers made faster keep their former definitions ------------------------------------

def _plain_body_by_substrings(body: bytes) -> bool:
    """plain_body as first written: substring searches."""
    return bool(body) and not (body.endswith(b" ") or b"\n\n" in body or b" \n" in body or b"\n#" in body
                               or any(space in body for space in (b"\t", b"\r", b"\x0b", b"\x0c", b"\x1c",
                                                                  b"\x1d", b"\x1e", b"\x1f")))


def test_plain_body_equals_its_substring_definition_on_every_short_body():
    alphabet = [b"\n", b" ", b"#", b"\t", b"\r", b"1", b"a"]
    bodies = [b"".join(chars) for size in range(7) for chars in itertools.product(alphabet, repeat=size)]
    assert [plain_body(body) for body in bodies] == [_plain_body_by_substrings(body) for body in bodies]


def test_tables_equal_pyarrow_from_pandas(simulated_run, campaign):
    """tables.to_arrow converts column by column what pa.Table.from_pandas converted."""
    result, _ = newcom.ingest_run(simulated_run, campaign)
    result["quarantine"] = pd.DataFrame({"file": ["uwb.log"], "line": np.array([3], dtype=np.int32),
                                         "text": ["x"], "reason": ["y"]})
    for name, frame in result.items():
        schema = tables.schema_for(name, frame)          # newcom has no 3-D truth: no optional z
        assert schema.names == [f.name for f in tables.SCHEMAS[name] if f.name != "z" or name != "truth"]
        expected = pa.Table.from_pandas(frame[schema.names], schema=schema, preserve_index=False)
        expected = expected.replace_schema_metadata({b"table": name.encode(), b"run": b"run-01"})
        assert tables.to_arrow(name, frame, {"run": "run-01"}).equals(expected, check_metadata=True)


def test_tables_refuse_a_missing_column_and_a_missing_value_where_none_is_allowed(simulated_run, campaign):
    truth = newcom.ingest_run(simulated_run, campaign)[0]["truth"]
    with pytest.raises(KeyError):
        tables.to_arrow("truth", truth.drop(columns="s"))
    with pytest.raises(ValueError, match="not nullable"):
        tables.to_arrow("truth", truth.assign(x=np.nan))


@pytest.mark.parametrize("quarantined", [0, 1, 2, 3])
@pytest.mark.parametrize("limits", [QuarantineLimits(0.2, 0.2), QuarantineLimits(0.1, 0.3), QuarantineLimits(0.3, 0.1)])
def test_within_limits_is_what_the_limit_check_says(tmp_path, quarantined, limits):
    inventory = {"a.log": {"data_lines": 10, "quarantined": quarantined}, "b.log": {"data_lines": 5, "quarantined": 0}}
    quarantine = pd.DataFrame({"file": ["a.log"] * quarantined, "reason": ["bad"] * quarantined})
    try:
        check_quarantine_limits(tmp_path, inventory, quarantine, limits, tmp_path / "kept.csv")
        passed = True
    except IngestError:
        passed = False
    assert within_limits(inventory, limits) == passed


def test_an_integer_speed_of_light_reads_uwb_line_by_line_with_the_same_ranges(simulated_run, campaign):
    """Python multiplies an integer c by tw_toa_ps exactly: the bulk path steps aside."""
    raw = read_raw(simulated_run / "uwb.log", Quarantine())
    integer_c = Campaign(campaign.name, campaign.format, {**campaign.spec, "speed_of_light_mps": 299792458},
                         campaign.source)
    assert newcom._uwb_plain(raw, 299792458, set(campaign.anchors_of("uwb")["anchor_id"])) is None
    expected = newcom._uwb_lines(raw, 299792458, dict(zip(campaign.anchors["anchor_id"], campaign.anchors["tech"])),
                                 Quarantine())
    pd.testing.assert_frame_equal(newcom.parse_uwb(raw, integer_c, Quarantine()), expected, check_exact=True)
    pd.testing.assert_frame_equal(newcom.parse_uwb(raw, campaign, Quarantine()), expected, check_exact=True)
