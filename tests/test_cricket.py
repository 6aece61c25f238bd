"""Cricket listener parser: the three line formats, real-world damage, and fuzzing."""

import hashlib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wsnloc.campaign import Campaign
from wsnloc.io.cricket import canonical_id, ingest_run, parse_listener
from wsnloc.io.rawlines import Quarantine, RawFile
from wsnloc.sim.cricket import simulate_run, speed_of_sound
from wsnloc.sim.seeding import run_seed_sequence

from conftest import ROOT

C = speed_of_sound(20.0)


@pytest.fixture(scope="module")
def cricket():
    return Campaign.load(ROOT / "config" / "campaigns" / "cricket.yaml")


def _parse(cricket, *lines):
    raw = RawFile(path=ROOT / "listener.log", header=[], lines=list(enumerate(lines, start=1)), sha256="",
                  n_lines=len(lines), n_records=len(lines))
    quarantine = Quarantine()
    ranges, rf_only = parse_listener(raw, cricket, quarantine)
    return ranges, rf_only, {line: reason for _, line, _, reason in quarantine.rows}


GOOD = "12034\tVR=2.0,ID=01:25:61:61:0b:00:00:42,SP=B3,DB=155,DR=4518,TM=4890,TS=22528"


def test_v2_line_with_host_time(cricket):
    ranges, rf_only, bad = _parse(cricket, GOOD)
    assert not bad and rf_only == 0
    row = ranges.iloc[0]
    assert row["anchor_id"] == "B3" and row["t"] == pytest.approx(12.034)
    assert row["range_m"] == pytest.approx(4518e-6 * C)          # DR preferred over DB


def test_keys_in_any_order_with_stray_spaces(cricket):
    line = "12034\t TS=22528 , DB=155,SP = B3,DR=4518, VR=2.0 "
    ranges, _, bad = _parse(cricket, line)
    assert not bad and ranges["range_m"].iloc[0] == pytest.approx(4518e-6 * C)


def test_rf_only_line_is_counted_not_tabled(cricket):
    ranges, rf_only, bad = _parse(cricket, "13102\tVR=2.0,ID=01:4c:61:61:0b:00:00:1f,SP=B5,TS=23596")
    assert len(ranges) == 0 and rf_only == 1 and not bad


def test_db_only_and_one_digit_id_bytes(cricket):
    ranges, _, bad = _parse(cricket, "12034\tVR=2.0,ID=1:25:61:61:b:0:0:42,DB=155,TS=22528")
    assert not bad and ranges["anchor_id"].iloc[0] == "B1" and ranges["range_m"].iloc[0] == pytest.approx(1.55)


def test_older_formats(cricket):
    ranges, _, bad = _parse(cricket, "100\t$Cricket2,ver=3.0,id=66,dist=17,duration=1435,time=1195",
                            "200\t$Cricket2,ver=3.0,space=B4,id=45,dist=11,duration=320")
    assert not bad
    assert ranges["anchor_id"].tolist() == ["B1", "B4"]            # id 66 = 0x42, the last byte of B1's ID
    assert ranges["range_m"].tolist() == pytest.approx([1435e-6 * C, 320e-6 * C])


def test_line_without_host_prefix_takes_time_from_ts(cricket):
    ranges, _, bad = _parse(cricket, "VR=2.0,SP=B2,DB=80,DR=2330,TS=22528")
    assert not bad and ranges["t"].iloc[0] == pytest.approx(22.528)


@pytest.mark.parametrize("line, reason", [
    ("12034\tVR=2.0,ID=01:25:61:61:0b:00:00:42,SP=B3,DB=15", "cut short"),
    ("12034\tVR=2.0,ID=01:25:61:61:0b:00:00:42,SP=B3,DB=155,DR=45,TS=1", "disagree"),
    ("12034\tVR=2.0,SP=B3,DB=155,DR=4518,TS=22528VR=2.0,SP=B4,DB=90,DR=2620,TS=22600", "run together"),
    ("12034\tVR=2.0,SP=B3,DB=155,DR=4518,TS=2252813102\tVR=2.0,SP=B5,TS=23596", "run together"),
    ("12034\tVR=2.0,SP=,DB=,TS=22528", "no beacon"),
    ("12034\tVR=2.0,SP=B9,DB=155,TS=22528", "unknown space"),
    ("12034\tVR=2.0,SP=B3,DB=155,DR=4518,TS=99999999999", "absurd counter"),
    ("12034\tVR=2.0,SP=B3,DB=9999999,TS=22528", "absurd range"),
    ("12034\tVR=2.0,SP=B3,DB=1x5,TS=22528", "not a number"),
    ("12o34\tVR=2.0,SP=B3,DB=155,TS=22528", "host time"),
    ("VR=2.0,SP=B3,DB=155", "cut short"),
])
def test_damaged_lines_are_quarantined(cricket, line, reason):
    ranges, _, bad = _parse(cricket, line)
    assert len(ranges) == 0 and reason in bad[1]


def test_unknown_space_id_falls_back_to_the_beacon_id(cricket):
    ranges, _, bad = _parse(cricket, GOOD.replace("SP=B3", "SP=ship"))
    assert not bad and ranges["anchor_id"].tolist() == ["B1"]          # the ID is B1's beacon_id
    _, _, bad = _parse(cricket, GOOD.replace("SP=B3", "SP=ship").replace("ID=01:25", "ID=07:25"))
    assert bad[1] == "unknown space id SP='ship' and unknown beacon id '07:25:61:61:0b:00:00:42'"


@pytest.mark.parametrize("line, reason", [
    ("12034\tVR=2.0,ID=01:25:61:61:0b:00:00:42,SP=B3,", "line cut short after a comma"),
    ("12034\tVR=2.0,ID=01:25:61:61:0b:00:00:42,SP=B3,D", "line cut short (ends with ',D')"),
    ("12034\tVR=2.0,ID=01:25:61:61:0b:00:00:42,SP=B3,DB=155,DR=4518", "a range but no TS field: line cut short"),
])
def test_cut_short_reasons(cricket, line, reason):
    _, _, bad = _parse(cricket, line)
    assert bad == {1: reason}


def test_rf_only_record_without_ts_is_valid(cricket):
    """The format (docs/raw-formats.md): DB, DR, TM and TS may all be missing on RF-only records."""
    ranges, rf_only, bad = _parse(cricket, "13102\tVR=2.0,ID=01:4c:61:61:0b:00:00:1f,SP=B5")
    assert len(ranges) == 0 and rf_only == 1 and not bad
    _, rf_only, bad = _parse(cricket, "VR=2.0,ID=01:4c:61:61:0b:00:00:1f,SP=B5")
    assert rf_only == 0 and "no timestamp" in bad[1]


def test_listener_log_alone_is_a_run(cricket, tmp_path):
    (tmp_path / "listener.log").write_text(GOOD + "\n")
    result, inventory = ingest_run(tmp_path, cricket)
    assert len(result["ranges"]) == 1 and result["imu"].empty and result["truth"].empty
    assert list(inventory) == ["listener.log"]


def test_time_going_backwards(cricket):
    ranges, _, bad = _parse(cricket, GOOD, GOOD.replace("12034", "11000"))
    assert len(ranges) == 1 and "backwards" in bad[2]


def test_canonical_id():
    assert canonical_id("1:25:61:61:b:0:0:42") == "01:25:61:61:0b:00:00:42"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.text(alphabet=st.characters(min_codepoint=9, max_codepoint=126), max_size=120))
def test_arbitrary_text_parses_or_is_quarantined(cricket, text):
    lines = [line for line in text.split("\n") if line.strip()]
    ranges, rf_only, bad = _parse(cricket, *lines)
    assert len(ranges) + rf_only + len(bad) == len(lines)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.integers(min_value=0, max_value=len(GOOD)), st.sampled_from(["", ",", "=", "\t", "VR=2.0,", " "]))
def test_mutilated_good_line_never_crashes(cricket, cut, junk):
    line = GOOD[:cut] + junk + GOOD[cut:]
    ranges, rf_only, bad = _parse(cricket, line)
    assert len(ranges) + rf_only + len(bad) == 1


def test_simulated_run_is_deterministic_and_ingests(cricket, tmp_path):
    seeds = run_seed_sequence(3, "cricket", "speed_40", 1)
    a = simulate_run(cricket, "speed_40", seeds, tmp_path / "a")
    b = simulate_run(cricket, "speed_40", seeds, tmp_path / "b")
    for name in ("listener.log", "imu.log", "truth.log"):
        assert hashlib.sha256((a / name).read_bytes()).digest() == hashlib.sha256((b / name).read_bytes()).digest()
    result, inventory = ingest_run(a, cricket)
    share = inventory["listener.log"]["quarantined"] / inventory["listener.log"]["data_lines"]
    assert len(result["ranges"]) > 300 and share < 0.03
    assert set(result["ranges"]["anchor_id"]) == {"B1", "B2", "B3", "B4", "B5", "B6"}


def test_simulated_wheel_odometry_follows_the_encoder_physics(cricket, tmp_path):
    """odometry.log of a simulated run: each wheel's integrated travel (v -/+ w b / 2) is the
    path's length -/+ b / 2 x the path's total turn, within its diameter scale (+-4 sigma), and
    the speed steps are the encoder quantum over a sample period averaged over two wheels."""
    import numpy as np

    run = simulate_run(cricket, "speed_40", run_seed_sequence(3, "cricket", "speed_40", 1), tmp_path / "r")
    tables, inventory = ingest_run(run, cricket)
    odometry, spec = tables["odometry"], cricket.spec["odometry"]
    assert inventory["odometry.log"]["quarantined"] == 0 and len(odometry) > 1000
    dt, half = 1.0 / spec["rate_hz"], spec["wheelbase_m"] / 2
    assert np.allclose(np.diff(odometry["t"]), dt)
    heading = np.unwrap(cricket.path.evaluate(np.linspace(0.0, cricket.path.length, 20001))["heading"])
    turned = heading[-1] - heading[0]
    assert turned == pytest.approx(7 * np.pi / 2, abs=1e-6)          # two laps of the rectangle, 7 corners
    for sign in (-1.0, 1.0):                                          # left, right wheel
        travel = float(((odometry["v_mps"] + sign * half * odometry["yaw_rate_rps"]) * dt).sum())
        assert abs(travel / (cricket.path.length + sign * half * turned) - 1.0) < 4 * spec["diameter_sigma"] + 0.002
    quantum = np.pi * spec["wheel_diameter_m"] / spec["encoder_counts_per_rev"] / dt / 2   # m/s, v = mean of 2 wheels
    cruising = odometry.loc[odometry["yaw_rate_rps"].abs() < 1e-9, "v_mps"]
    steps = (cruising - cruising.median()) / quantum
    assert cruising.nunique() > 1 and np.all(np.abs(steps - np.round(steps)) < 0.2)


def test_odometry_log_is_ingested_with_its_damaged_lines_quarantined(cricket, tmp_path):
    run = simulate_run(cricket, "speed_20", run_seed_sequence(3, "cricket", "speed_20", 1), tmp_path / "r")
    (run / "odometry.log").write_text("# cricket-odometry v1\n# t_ms v_mmps yaw_mradps\n"
                                      "10040 200 0\n10080 201\n10120 20x 0\n10160 9000 0\n10160 199 12\n"
                                      "10200 198 -30000\n10240 202 -5\n")
    tables, inventory = ingest_run(run, cricket)
    odometry = tables["odometry"]
    assert odometry[["t", "v_mps", "yaw_rate_rps", "line"]].values.tolist() == [
        [10.04, 0.2, 0.0, 3], [10.16, 0.199, 0.012, 7], [10.24, 0.202, -0.005, 9]]
    q = tables["quarantine"]
    reasons = dict(zip(q.loc[q["file"] == "odometry.log", "line"], q.loc[q["file"] == "odometry.log", "reason"]))
    assert reasons == {4: "expected 3 fields 't_ms v_mmps yaw_mradps', found 2",
                       5: "v_mmps='20x' is not a number", 6: "speed 9 m/s beyond 5 m/s",
                       8: "yaw rate -30 rad/s beyond 10 rad/s"}
    assert inventory["odometry.log"]["quarantined"] == 4
    (run / "odometry.log").write_text("# cricket-imu v1\n10040 200 0\n")
    with pytest.raises(Exception, match="odometry"):
        ingest_run(run, cricket)
