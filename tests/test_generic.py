"""Generic adapter on hand-written tables, and the real UWB dataset through it."""


import numpy as np
import pandas as pd
import pytest

from wsnloc.campaign import Campaign
from wsnloc.cli import main
from wsnloc.errors import IngestError
from wsnloc.estimators import registry
from wsnloc.estimators.run_data import RunData
from wsnloc.io.convert import convert_cucudasluv
from wsnloc.io import tables
from wsnloc.io.generic import ingest_run
from wsnloc.metrics.ranging import range_errors
from wsnloc.metrics.tracking import score
from wsnloc.studies import run_cell

from conftest import ROOT

REAL = ROOT.parent / "shared" / "realdata" / "cucudasluv-uwb"
CAMPAIGN = ROOT / "config" / "campaigns" / "cucudasluv.yaml"


@pytest.fixture(scope="module")
def generic():
    return Campaign.load(CAMPAIGN)


@pytest.fixture
def run_dir(tmp_path):
    (tmp_path / "anchors.csv").write_text("anchor_id,tech,x,y,z\nA1,uwb,0,0,1.0\nA2,uwb,10,0,1.0\nA3,uwb,0,10,\n")
    (tmp_path / "ranges.csv").write_text(
        "t,anchor_id,range_m\n0.0,A1,5.0\n0.1,A2,nan\n0.2,A9,3.0\n0.3,A3, 7.5\n0.25,A1,4.0\n0.4,A2,abc\n0.5,,1.0\n")
    (tmp_path / "truth.csv").write_text("t,x,y\n0,3,4\n1,6,8\n")
    return tmp_path


def test_generic_tables_and_quarantine(run_dir, generic):
    result, inventory = ingest_run(run_dir, generic)
    ranges = result["ranges"]
    # rows out of time order are sorted (stable), not dropped: line 6 (t = 0.25 s) before line 5
    assert ranges[["anchor_id", "range_m", "line"]].values.tolist() == [["A1", 5.0, 2], ["A1", 4.0, 6],
                                                                        ["A3", 7.5, 5]]
    q = result["quarantine"].set_index("line")["reason"].to_dict()
    assert q == {3: "range_m 'nan' is not a finite number", 4: "unknown anchor 'A9' (not in anchors.csv)",
                 7: "range_m 'abc' is not a finite number", 8: "anchor_id is empty"}
    assert inventory["ranges.csv"]["quarantined"] == 4 and inventory["ranges.csv"]["reordered"] == 1
    assert inventory["ranges.csv"]["unknown_anchors"] == {"A9": 1}
    assert result["truth"]["s"].tolist() == [0.0, 5.0]
    assert np.isnan(result["anchors"]["z"].iloc[2]) and result["ranges"]["status"].tolist() == [0, 0, 0]


def test_a_row_logged_twice_is_quarantined_once_and_the_first_kept(run_dir, generic):
    """A row equal in every value to an earlier usable one (line 9 repeats line 2; line 10 repeats
    line 5 with its stray space; line 11 differs in one value) is refused with the first row's line;
    a repeat of a refused row (line 12 of line 4) keeps its own reason."""
    with open(run_dir / "ranges.csv", "a") as out:
        out.write("0.0,A1,5.0\n0.3,A3,7.5\n0.3,A3,7.6\n0.2,A9,3.0\n")
    result, inventory = ingest_run(run_dir, generic)
    q = result["quarantine"].set_index("line")["reason"].to_dict()
    assert q[9] == "a repeat of line 2 (every value equal)" and q[10] == "a repeat of line 5 (every value equal)"
    assert 11 not in q and q[12] == "unknown anchor 'A9' (not in anchors.csv)"
    assert result["ranges"]["line"].tolist() == [2, 6, 5, 11]
    assert inventory["ranges.csv"]["quarantined"] == 7


def test_generic_parquet_input(run_dir, generic):
    pd.read_csv(run_dir / "truth.csv").to_parquet(run_dir / "truth.parquet")
    (run_dir / "truth.csv").unlink()
    result, _ = ingest_run(run_dir, generic)
    assert len(result["truth"]) == 2 and result["truth"]["line"].tolist() == [1, 2]


def test_parquet_missing_values_read_as_empty_fields(run_dir):
    anchors = pd.DataFrame({"anchor_id": ["A1", "A2", "A3"], "tech": "uwb", "x": [0.0, 10.0, 0.0],
                            "y": [0.0, 0.0, 10.0], "z": [1.0, None, 2.0]})
    anchors.to_parquet(run_dir / "anchors.parquet")
    (run_dir / "anchors.csv").unlink()
    result, _ = ingest_run(run_dir)
    assert result["anchors"]["z"].tolist()[::2] == [1.0, 2.0] and np.isnan(result["anchors"]["z"].iloc[1])
    assert "anchors.parquet" not in set(result["quarantine"]["file"])


def test_three_d_true_range_uses_the_tag_height(run_dir, generic):
    result, _ = ingest_run(run_dir, generic)
    errors = range_errors(result["ranges"], result["truth"], generic, result["anchors"])
    # A1 at height 1.0 = tag height: 3-D equals 2-D, |(3, 4)| = 5.
    assert errors["error_m"].iloc[0] == pytest.approx(0.0)


def test_missing_required_file_or_column(run_dir, generic):
    (run_dir / "ranges.csv").write_text("t,anchor,range_m\n0,A1,1\n")
    with pytest.raises(IngestError, match=r"ranges.csv: missing column\(s\) \['anchor_id'\]"):
        ingest_run(run_dir, generic)
    (run_dir / "ranges.csv").unlink()
    with pytest.raises(IngestError, match="needs ranges"):
        ingest_run(run_dir, generic)


@pytest.mark.parametrize("per_second, unit", [(1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds")])
def test_time_stamps_in_a_finer_unit_than_seconds_are_refused_with_the_factor(run_dir, generic, per_second, unit):
    """A logger's Unix milliseconds (or finer) read as seconds put the run thousands of years
    ahead; a short run of them passes the one-day span check, so the unit is checked apart."""
    (run_dir / "ranges.csv").write_text("t,anchor_id,range_m\n" + "".join(
        f"{(1.7e9 + 0.1 * k) * per_second:.0f},A{1 + k % 3},{5.0 + 0.01 * k}\n" for k in range(50)))
    with pytest.raises(IngestError, match=rf"ranges.csv: column t must be in seconds; its median .* looks like "
                                          rf"Unix {unit} .*divide t by {per_second:.0f}"):
        ingest_run(run_dir, generic)
    (run_dir / "ranges.csv").write_text("t,anchor_id,range_m\n" + "".join(
        f"{1.7e9 + 0.1 * k:.1f},A{1 + k % 3},{5.0 + 0.01 * k}\n" for k in range(50)))
    (run_dir / "truth.csv").write_text("t,x,y\n1700000000,3,4\n1700000010,6,8\n")
    assert len(ingest_run(run_dir, generic)[0]["ranges"]) == 50          # Unix seconds pass


def test_cli_ingests_generic_and_keeps_anchor_heights(run_dir, tmp_path, capsys):
    assert main(["ingest", "--format", "generic", "--campaign", str(CAMPAIGN), "--max-quarantine-share-per-file", "1",
                 "--max-quarantine-share", "1", str(run_dir), str(tmp_path / "out")]) == 0
    assert "ranges.csv" in capsys.readouterr().out
    anchors = tables.read(tmp_path / "out" / "anchors.parquet")
    assert anchors["z"].tolist()[:2] == [1.0, 1.0] and tables.unit_of(tmp_path / "out" / "anchors.parquet", "z") == "m"


needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"real dataset not present at {REAL} (../shared missing)")


@needs_real
def test_real_dataset_converts_and_ingests(tmp_path, generic):
    runs = [run.run_dir for run in convert_cucudasluv(REAL, tmp_path)]
    assert {p.parent.name for p in runs} == {"los", "nlos"}
    los = next(p for p in runs if p.parent.name == "los")
    result, inventory = ingest_run(los, generic)
    assert len(result["anchors"]) == 4 and len(result["ranges"]) > 5000
    assert sum(f["quarantined"] for f in inventory.values()) == 0
    errors = range_errors(result["ranges"], result["truth"], generic, result["anchors"])
    assert abs(errors["error_m"].median()) < 0.2           # LOS: no bias beyond 20 cm against 3-D truth


@needs_real
def test_real_dataset_through_the_cli(tmp_path, capsys):
    assert main(["convert", "cucudasluv", str(REAL), str(tmp_path)]) == 0
    assert "los" in capsys.readouterr().out


def test_estimators_on_noise_free_3d_ranges_one_anchor_at_a_time(tmp_path, generic):
    anchors = np.array([[0.0, 0.0, 2.0], [20.0, 0.0, 0.5], [0.0, 20.0, 2.0], [20.0, 20.0, 0.5]])
    (tmp_path / "anchors.csv").write_text("anchor_id,tech,x,y,z\n" + "".join(
        f"A{i},uwb,{x},{y},{z}\n" for i, (x, y, z) in enumerate(anchors)))
    t = np.arange(0.0, 60.0, 0.1)
    path = np.column_stack([5 + 0.1 * t, 5 + 0.05 * t])
    rows = []
    for k, tk in enumerate(t):
        i = k % 4
        d = np.sqrt(np.sum((path[k] - anchors[i, :2]) ** 2) + (anchors[i, 2] - 1.0) ** 2)   # tag at 1.0 m
        rows.append(f"{tk:.2f},A{i},{d:.6f}\n")
    (tmp_path / "ranges.csv").write_text("t,anchor_id,range_m\n" + "".join(rows))
    (tmp_path / "truth.csv").write_text("t,x,y\n" + "".join(f"{a:.2f},{x},{y}\n" for a, (x, y) in zip(t, path)))
    tables, _ = ingest_run(tmp_path, generic)
    data = RunData(tables, generic)
    for name, params in (("tracker", {"range_sigma_m": 0.05, "accel_sigma_mps2": 0.05}),
                         ("multilateration", {}), ("ekf", {"range_sigma_m": 0.05, "accel_sigma_mps2": 0.05})):
        scored = score(registry.run(name, data, params), tables["truth"])
        assert np.nanmedian(scored["error_m"]) < 0.06, name


@needs_real
def test_study_cells_on_the_real_dataset(tmp_path, generic):
    runs = {}
    for run in convert_cucudasluv(REAL, tmp_path):
        tables, _ = ingest_run(run.run_dir, generic)
        runs[run.run_dir.parent.name] = tables
    p = registry.get("ekf").resolve({"measurements": "hybrid", "max_range_m": 100.0, "accel_sigma_mps2": 1.0})
    estimates, metrics = run_cell("cucudasluv/nlos", "hybrid", "ekf", p, ["all"], {"nlos": runs["nlos"]}, generic,
                                  donors={"los": runs["los"]})
    assert metrics["rss_model"].iloc[0] == "fitted on los"          # a donor of the same dataset
    assert metrics["median"].iloc[0] < 1.5 and metrics["availability"].iloc[0] > 0.9
    p = registry.get("tracker").resolve({"max_range_m": 100.0})
    _, metrics = run_cell("cucudasluv/nlos", "tracker", "tracker", p, ["all"], {"nlos": runs["nlos"]}, generic)
    assert metrics["median"].iloc[0] < 1.5 and metrics["availability"].iloc[0] > 0.9
