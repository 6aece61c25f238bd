"""Raw-log parsers on hand-written fixtures, including the damage real logs carry."""

import numpy as np
import pandas as pd
import pytest
from conftest import ROOT
from hypothesis import given, settings
from hypothesis import strategies as st

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.io import tables
from wsnloc.io.ingest import ingest_one, ingest_scenario
from wsnloc.io.limits import QuarantineLimits
from wsnloc.io.newcom import ingest_run, parse_imu
from wsnloc.io.rawlines import Quarantine, read_raw

from test_timeorder import ordered_by_brute_force

UWB = """# newcom-uwb v1
# t_ms anchor tw_toa_ps status
12500 U01 51234 0
12510 U04 80211 0\r
12520 U09 0 7
12530 U99 41000 0
12540 Z01 41000 0
12550 U02 4x000 0
12560 U03 41000
12400 U05 41000 0
12570   U06   41000   0   \t
12580 U07 nan 0
"""

ZIGBEE = """# newcom-zigbee v1
# t_ms seq n anchor:rssi_dbm ...
12550 251 3 Z01:-61 Z02:-70 Z11:-83
12600 252 2 Z01:-61 Z02:-70 Z11:-83
12650 253 1 Z01
12700 254 1 Z77:-60
12750 255 2 Z01:-60 Z01:-62
12800 0 1 U01:-60
12850 1 1 Z03:-7.5
12900 2 0
"""

IMU = """# newcom-imu v1
# accel_lsb_per_g=1024 gyro_lsb_per_dps=131.072
# t_ms ax ay az gz
12500.000 12 -3 1021 5
12502.001 1024 0 1024 131
12502.001 1 1 1 1
12504.000 1 1
12506.000 1 1 1.5 1
12508.000 -1024 0 0 -262
"""

TRUTH = """# newcom-truth v1
# t_ms rail_m
12500 0.00
12540 20.5708
12580 99.0
12520 3.00
12620 abc
12660 24.57
"""


@pytest.fixture
def run_dir(tmp_path):
    folder = tmp_path / "run-01"
    folder.mkdir()
    for name, text in (("uwb.log", UWB), ("zigbee.log", ZIGBEE), ("imu.log", IMU), ("truth.log", TRUTH)):
        (folder / name).write_bytes(text.encode("ascii"))
    return folder


@pytest.fixture
def parsed(run_dir, campaign):
    return ingest_run(run_dir, campaign)


def _reasons(quarantine, file):
    q = quarantine[quarantine["file"] == file]
    return dict(zip(q["line"], q["reason"]))


def test_uwb_lines(parsed):
    result, _ = parsed
    ranges = result["ranges"]
    assert ranges["anchor_id"].tolist() == ["U01", "U04", "U09", "U06"]
    assert ranges["line"].tolist() == [3, 4, 5, 11]
    c = 299792458.0
    assert ranges["range_m"].iloc[0] == pytest.approx(c * 51234e-12 / 2)
    assert ranges["t"].iloc[0] == pytest.approx(12.5)
    assert ranges["status"].tolist() == [0, 0, 7, 0]          # flagged record kept with its status
    reasons = _reasons(result["quarantine"], "uwb.log")
    assert set(reasons) == {6, 7, 8, 9, 10, 12}
    assert "unknown anchor 'U99'" in reasons[6]
    assert "zigbee anchor, not uwb" in reasons[7]
    assert "tw_toa_ps is not an integer" in reasons[8]
    assert "expected 4 fields" in reasons[9]
    assert "time goes backwards" in reasons[10]
    assert "tw_toa_ps is not an integer: 'nan'" in reasons[12]


def test_zigbee_lines(parsed):
    result, _ = parsed
    rss = result["rss"]
    assert rss["line"].unique().tolist() == [3]
    assert rss["rss_dbm"].tolist() == [-61.0, -70.0, -83.0] and rss["seq"].tolist() == [251] * 3
    reasons = _reasons(result["quarantine"], "zigbee.log")
    assert "n = 2 but 3" in reasons[4]
    assert "not anchor:rssi_dbm" in reasons[5]
    assert "unknown anchor 'Z77'" in reasons[6]
    assert "appears twice" in reasons[7]
    assert "uwb anchor, not zigbee" in reasons[8]
    assert "rssi of Z03 is not an integer" in reasons[9]
    assert 10 not in reasons                          # an empty broadcast is valid, with no samples


def test_imu_lines_are_converted_to_si(parsed):
    result, _ = parsed
    imu = result["imu"]
    assert imu["line"].tolist() == [4, 5, 9]
    g = 9.80665
    assert imu["ax"].iloc[1] == pytest.approx(g) and imu["az"].iloc[1] == pytest.approx(g)
    assert imu["gz"].iloc[1] == pytest.approx(np.deg2rad(131 / 131.072))
    assert imu["ax"].iloc[2] == pytest.approx(-g)
    reasons = _reasons(result["quarantine"], "imu.log")
    assert "time repeats" in reasons[6]
    assert "expected 5 fields" in reasons[7]
    assert "az is not an integer" in reasons[8]


def test_truth_becomes_xy_on_the_rail(parsed):
    result, _ = parsed
    truth = result["truth"]
    assert truth["line"].tolist() == [3, 4, 8]
    assert (truth["x"].iloc[0], truth["y"].iloc[0]) == pytest.approx((2.5, 7.5))
    assert (truth["x"].iloc[1], truth["y"].iloc[1]) == pytest.approx((2.5 + 20.5708, 7.5), abs=1e-3)   # straight rail
    reasons = _reasons(result["quarantine"], "truth.log")
    assert "outside the path" in reasons[5]
    assert "time goes backwards" in reasons[6]
    assert "rail_m is not a number" in reasons[7]


def test_inventory_counts_and_checksums(parsed, run_dir):
    _, inventory = parsed
    assert inventory["uwb.log"]["data_lines"] == 10 and inventory["uwb.log"]["quarantined"] == 6
    assert len(inventory["imu.log"]["sha256"]) == 64


def test_non_ascii_and_blank_lines(run_dir, campaign):
    (run_dir / "uwb.log").write_bytes(b"# newcom-uwb v1\n12500 U01 51234 0\n\n12510 U\xc3\xa9 1 0\n")
    result, _ = ingest_run(run_dir, campaign)
    assert len(result["ranges"]) == 1
    assert _reasons(result["quarantine"], "uwb.log") == {4: "not ASCII text"}


def test_missing_imu_scale_header_is_an_error(run_dir, campaign):
    (run_dir / "imu.log").write_text("# newcom-imu v1\n12500.000 1 2 3 4\n")
    with pytest.raises(IngestError, match=r"imu.log: header must give 'accel_lsb_per_g"):
        ingest_run(run_dir, campaign)


def test_wrong_file_is_an_error(run_dir, campaign):
    (run_dir / "uwb.log").write_text(ZIGBEE)
    with pytest.raises(IngestError, match=r"uwb.log:1: expected a '\*-uwb' log"):
        ingest_run(run_dir, campaign)


def test_missing_file_is_an_error(run_dir, campaign):
    (run_dir / "truth.log").unlink()
    with pytest.raises(IngestError, match=r"truth.log: cannot read"):
        ingest_run(run_dir, campaign)


def test_tables_have_units_in_the_schema(run_dir, campaign, tmp_path):
    out = tmp_path / "out"
    ingest_one("newcom", run_dir, campaign, out)
    assert tables.unit_of(out / "ranges.parquet", "range_m") == "m"
    assert tables.unit_of(out / "imu.parquet", "gz") == "rad/s"
    assert tables.unit_of(out / "rss.parquet", "rss_dbm") == "dBm"
    quarantine = tables.read(out / "quarantine.parquet")
    assert set(quarantine.columns) == {"file", "line", "text", "reason"}
    assert len(quarantine) == 6 + 6 + 3 + 3   # uwb, zigbee, imu, truth


def test_tables_read_back_as_the_former_zstd_files(parsed, tmp_path):
    """tables.write (LZ4, dictionaries for strings only) and tables.read (one file, no threads)
    give the tables the former writer (zstd, dictionaries everywhere) and pq.read_table gave:
    same values, types, nulls, units and metadata; `columns` picks and orders, a missing one
    is a KeyError."""
    import pyarrow.parquet as pq

    result, _ = parsed
    estimates = pd.DataFrame({"run": ["r1", "r1"], "subset": ["all", "all"], "t": [1.0, 2.0], "x": [1.0, np.nan],
                              "y": [2.0, np.nan], "true_x": [1.0, 1.5], "true_y": [2.0, 2.5], "error_m": [0.0, np.nan],
                              **{name: [np.nan, 1.0] for name in ("p_xx", "p_xy", "p_yy", "n_meas", "nis")}})
    for name, frame in [*result.items(), ("estimates", estimates)]:
        path, former = tmp_path / f"{name}.parquet", tmp_path / f"{name}.zstd.parquet"
        tables.write(name, frame, path, {"format": "newcom"})
        pq.write_table(tables.to_arrow(name, frame, {"format": "newcom"}), former, compression="zstd")
        assert pq.read_table(path).equals(pq.read_table(former), check_metadata=True)
        assert pq.read_table(path).schema.equals(pq.read_table(former).schema, check_metadata=True)
        pd.testing.assert_frame_equal(tables.read(path), pq.read_table(former).to_pandas())
    assert pq.read_table(tmp_path / "estimates.parquet").column("x").null_count == 1
    assert list(tables.read(tmp_path / "imu.parquet", columns=["gz", "t"]).columns) == ["gz", "t"]
    with pytest.raises(KeyError, match="no column nope"):
        tables.read(tmp_path / "imu.parquet", columns=["t", "nope"])


def test_quarantine_share_limit_fails_loudly(run_dir, campaign, tmp_path):
    """Per run: 18 of the 30 records of the fixture are quarantined (6 + 6 + 3 + 3 of 10 + 8 + 6 + 6)."""
    limits = QuarantineLimits(per_run=0.5, per_file=1.0)
    with pytest.raises(IngestError, match=r"run-01: 60.0% of the run's records .* 'ingest.max_quarantine_share' = "
                                          r"50.0% .* quarantine table: .*kept/run-01.quarantine.csv"):
        ingest_scenario("newcom", {"run-01": str(run_dir)}, campaign, tmp_path / "out", limits, tmp_path / "kept")
    assert len(pd.read_csv(tmp_path / "kept" / "run-01.quarantine.csv")) == 18


def test_empty_logs_give_empty_tables(run_dir, campaign):
    for name in ("uwb.log", "zigbee.log", "truth.log"):
        (run_dir / name).write_text("")
    result, _ = ingest_run(run_dir, campaign)
    assert len(result["ranges"]) == len(result["rss"]) == len(result["truth"]) == 0
    assert list(result["ranges"].columns) == tables.SCHEMAS["ranges"].names


def test_damaged_line_in_a_simulated_log(simulated_run, campaign, tmp_path):
    """A real-world cut line appended to a simulated log is quarantined with file and line."""
    damaged = tmp_path / "run"
    damaged.mkdir()
    for p in simulated_run.iterdir():
        (damaged / p.name).write_bytes(p.read_bytes())
    lines = (damaged / "uwb.log").read_text().splitlines()
    (damaged / "uwb.log").write_text("\n".join(lines + ["999999 U0"]) + "\n")
    result, _ = ingest_run(damaged, campaign)
    q = result["quarantine"]
    assert q[["file", "line", "text"]].values.tolist() == [["uwb.log", len(lines) + 1, "999999 U0"]]
    assert len(result["ranges"]) == len(lines) - 2


def _imu_line_by_line(lines):
    """Reference for parse_imu: the spec applied one line at a time (5 fields, finite t_ms,
    integer counts), then the fewest lines refused so that time increases strictly
    (ties to the earliest lines), by brute force."""
    parsed, refused = [], []
    for number, text in enumerate(lines, start=4):
        fields = text.split()
        try:
            t_ms = float(fields[0])
            counts = [int(f) for f in fields[1:]]
            usable = len(fields) == 5 and np.isfinite(t_ms)
        except (ValueError, IndexError):
            usable = False
        if usable:
            parsed.append((number, t_ms, *counts))
        else:
            refused.append(number)
    kept = ordered_by_brute_force([p[1] for p in parsed], strict=True)
    refused += [p[0] for i, p in enumerate(parsed) if i not in kept]
    return [parsed[i] for i in kept], sorted(refused)


imu_numbers = st.sampled_from(["0", "7", "-12", "1021", "+5", "007", "1.5", "x", "", "nan", "1e3", "99999"])
imu_lines = st.lists(st.tuples(st.floats(0, 50, allow_nan=False).map(lambda t: f"{12500 + t:.3f}"),
                               st.lists(imu_numbers, min_size=3, max_size=5), st.sampled_from([" ", "  ", "\t"]))
                     .map(lambda p: p[2].join([p[0], *p[1]])), max_size=40)


@settings(max_examples=60, deadline=None)
@given(lines=imu_lines)
def test_bulk_imu_parsing_equals_line_by_line(lines, tmp_path_factory):
    """Regular lines are converted in bulk, the others one by one: the table and the
    quarantine are those of applying the format line by line, in file order."""
    folder = tmp_path_factory.mktemp("imu")
    header = "".join(IMU.splitlines(keepends=True)[:3])       # format, scale factors, columns
    (folder / "imu.log").write_text(header + "".join(line + "\n" for line in lines))
    campaign = Campaign.load(ROOT / "config" / "campaigns" / "newcom.yaml")
    quarantine = Quarantine()
    imu = parse_imu(read_raw(folder / "imu.log", quarantine), campaign, quarantine)
    accepted, refused = _imu_line_by_line(lines)
    assert imu["line"].tolist() == [a[0] for a in accepted]
    assert imu["t"].tolist() == [a[1] / 1000.0 for a in accepted]
    g = campaign.spec["gravity_mps2"]
    assert imu["ax"].tolist() == [a[2] / 1024 * g for a in accepted]
    assert imu["gz"].tolist() == [np.deg2rad(a[5] / 131.072) for a in accepted]
    assert quarantine.frame()["line"].tolist() == refused


def test_an_imu_count_beyond_any_adc_is_quarantined(run_dir, campaign):
    (run_dir / "imu.log").write_text(IMU + "12510.000 1 1 1 " + "9" * 400 + "\n")
    result, _ = ingest_run(run_dir, campaign)
    assert "beyond" in _reasons(result["quarantine"], "imu.log")[10]


@pytest.mark.parametrize("rows", [[], [("imu.log", 5, "1 2", "expected 5 fields")],
                                  [("uwb.log", n, f"line {n}", f"reason {n % 3}") for n in range(1, 300)]])
def test_quarantine_frame_is_the_cast_frame_of_its_rows(rows):
    """Quarantine.frame builds its typed columns directly: the frame of the former
    construction (a frame of the row tuples cast to str / int32), empty or not."""
    former = pd.DataFrame(rows, columns=["file", "line", "text", "reason"]).astype(
        {"file": str, "line": "int32", "text": str, "reason": str})
    pd.testing.assert_frame_equal(Quarantine(rows=list(rows)).frame(), former)
