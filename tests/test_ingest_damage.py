"""Issue 14's acceptance: ingest survives real-world damage without losing good data.

One timestamp glitch, garbage in one file, unsorted and malformed generic tables, a real
Cricket listener capture alone; and, per format, random damage of each kind: every
intact line is kept with its values, every damaged line is quarantined with file and line.
"""

import re
import shutil
from functools import cache

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from wsnloc.campaign import Campaign
from wsnloc.cli import main
from wsnloc.errors import IngestError
from wsnloc.io import cricket, generic, newcom
from wsnloc.io.ingest import ingest_scenario
from wsnloc.io.limits import QuarantineLimits
from wsnloc.io.rawlines import Quarantine, read_raw
from wsnloc.sim.cricket import speed_of_sound

from conftest import ROOT, small_workflow, snakemake

CRICKET = ROOT / "config" / "campaigns" / "cricket.yaml"
DAMAGE = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                          HealthCheck.too_slow])


def _copy(run, target):
    if target.exists():
        shutil.rmtree(target)
    shutil.copytree(run, target)
    return target


def _log_lines(path):
    return path.read_text().splitlines()


# --- a timestamp glitch, garbage in one file ---------------------------------------------

def test_one_far_future_line_in_uwb_log_is_the_only_one_quarantined(simulated_run, campaign, tmp_path):
    run = _copy(simulated_run, tmp_path / "run")
    lines = _log_lines(run / "uwb.log")
    glitch = 40                                           # a data line (index in the file, 0-based)
    t_ms, rest = lines[glitch].split(" ", 1)
    lines[glitch] = f"{int(t_ms) + 10**9} {rest}"
    (run / "uwb.log").write_text("\n".join(lines) + "\n")
    clean, _ = newcom.ingest_run(simulated_run, campaign)
    result, inventory = newcom.ingest_run(run, campaign)
    q = result["quarantine"]
    assert q[["file", "line"]].values.tolist() == [["uwb.log", glitch + 1]]
    assert q["reason"].iloc[0].startswith("time jumps ahead")
    expected = clean["ranges"][clean["ranges"]["line"] != glitch + 1].reset_index(drop=True)
    pd.testing.assert_frame_equal(result["ranges"], expected)
    assert inventory["uwb.log"]["quarantined"] == 1


def test_garbage_in_one_file_stops_the_scenario_naming_that_file(simulated_run, campaign, tmp_path):
    """40% of uwb.log is garbage: about 1% of the run's lines, but 40% of that file."""
    run = _copy(simulated_run, tmp_path / "run")
    lines = _log_lines(run / "uwb.log")
    header, data = lines[:2], lines[2:]
    n_bad = round(len(data) * 0.4 / 0.6)
    garbage = [f"{10000 + k} U0{k % 9 + 1} 4{k}x 0" if k % 2 else "\x7f%%@!" for k in range(n_bad)]
    mixed = [line for pair in zip(data, garbage) for line in pair] + data[len(garbage):]
    (run / "uwb.log").write_text("\n".join(header + mixed) + "\n")
    with pytest.raises(IngestError) as stop:
        ingest_scenario("newcom", {"run-01": str(run)}, campaign, tmp_path / "out", QuarantineLimits(),
                        tmp_path / "logs")
    message = str(stop.value)
    assert message.startswith(f"{run / 'uwb.log'}: 40.0% of its {len(data) + n_bad} records are quarantined")
    assert "'ingest.max_quarantine_share_per_file' = 20.0%" in message
    assert f"{n_bad // 2} x tw_toa_ps is not an integer: '…'" in message
    assert f"{n_bad - n_bad // 2} x expected N fields '…', found N" in message
    kept = pd.read_csv(tmp_path / "logs" / "run-01.quarantine.csv")
    assert f"quarantine table: {tmp_path / 'logs' / 'run-01.quarantine.csv'}" in message
    assert len(kept) == n_bad and set(kept["file"]) == {"uwb.log"}


def test_unknown_anchor_dominating_is_named_with_its_count(simulated_run, campaign, tmp_path):
    run = _copy(simulated_run, tmp_path / "run")
    lines = _log_lines(run / "uwb.log")
    for i in range(2, len(lines), 3):
        lines[i] = lines[i].replace(lines[i].split()[1], "U77")
    n = len(range(2, len(lines), 3))
    (run / "uwb.log").write_text("\n".join(lines) + "\n")
    with pytest.raises(IngestError, match=rf"uwb.log: 33.\d% .* dominant reasons: {n} x unknown anchor '…' \(not in "
                                          rf"the campaign file\); most frequent values: 'U77' \({n}\)"):
        ingest_scenario("newcom", {"run-01": str(run)}, campaign, tmp_path / "out", QuarantineLimits(),
                        tmp_path / "logs")


def test_a_failing_ingest_job_keeps_its_quarantine_in_the_logs(simulated_run, tmp_path):
    """The workflow on real logs: the ingest job stops, names the file, and the quarantine
    table survives in logs/ although Snakemake deletes the failed job's outputs."""
    raw = tmp_path / "raw" / "constant" / "run-01"
    _copy(simulated_run, raw)
    work = small_workflow(tmp_path / "work")
    config = yaml.safe_load((work / "config" / "config.yaml").read_text())
    config["datasets"]["newcom"].update(source="logs", raw_dir=str(tmp_path / "raw"), scenarios=["constant"])
    del config["datasets"]["newcom"]["scenario_runs"], config["studies"]["workbench_spatial"]   # simulated only
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(config))
    target = "data/processed/newcom/constant/tables/shard-1"
    intact = snakemake(work, "--cores", "1", target)
    assert intact.returncode == 0, intact.stderr[-3000:]
    assert (work / target / "inventory.json").is_file()
    lines = _log_lines(raw / "zigbee.log")
    (raw / "zigbee.log").write_text("\n".join(lines[:2] + [f"{text[:12]}" for text in lines[2:]]) + "\n")
    result = snakemake(work, "--cores", "1", "--forcerun", "ingest", target)
    assert result.returncode != 0
    log = (work / "logs" / "ingest" / "newcom-constant-shard-1.log").read_text()
    assert f"{raw / 'zigbee.log'}: 100.0% of its {len(lines) - 2} records are quarantined" in log
    kept = pd.read_csv(work / "logs" / "ingest" / "newcom-constant-shard-1" / "run-01.quarantine.csv")
    assert len(kept) == len(lines) - 2 and not (work / target).exists()


def test_a_damaged_simulated_log_fails_its_formats_ingest_job_and_keeps_the_quarantine(tmp_path):
    """Simulated logs are ingested one job per format, whose inputs are the run folders: a raw
    log damaged by hand is ingested again with --forcerun (the simulation does not re-run),
    the job names the scenario and the file, and the quarantine is kept under the job's log
    folder, per scenario."""
    work = small_workflow(tmp_path / "work")
    target = "data/processed/newcom/constant/tables/shard-1"
    intact = snakemake(work, "--cores", "1", target)
    assert intact.returncode == 0, intact.stderr[-3000:]
    raw = work / "data" / "raw" / "newcom" / "constant" / "run-01" / "zigbee.log"
    lines = _log_lines(raw)
    raw.write_text("\n".join(lines[:2] + [text[:12] for text in lines[2:]]) + "\n")
    planned = snakemake(work, "-n", target, "--forcerun", "ingest_newcom_shard1")
    planned = planned.stdout + planned.stderr
    assert "ingest_newcom_shard1" in planned and "simulate_newcom_shard1" not in planned, planned
    result = snakemake(work, "--cores", "1", target, "--forcerun", "ingest_newcom_shard1")
    assert result.returncode != 0
    log = (work / "logs" / "ingest" / "newcom-shard-1.log").read_text()
    assert f"newcom/constant: data/raw/newcom/constant/run-01/zigbee.log: 100.0% of its {len(lines) - 2} records" in log
    kept = pd.read_csv(work / "logs" / "ingest" / "newcom-shard-1" / "newcom-constant" / "run-01.quarantine.csv")
    assert len(kept) == len(lines) - 2 and not (work / target).exists()
    assert raw.read_text().splitlines()[2] == lines[2][:12]


# --- the generic format --------------------------------------------------------------------

def _noisy_generic_run(folder, rng):
    """Four anchors with heights, a tag at 1 m on a straight walk, ranges with 0.2 m noise."""
    folder.mkdir(parents=True, exist_ok=True)
    anchors = np.array([[0.0, 0.0, 2.0], [30.0, 0.0, 0.5], [0.0, 30.0, 2.0], [30.0, 30.0, 0.5]])
    (folder / "anchors.csv").write_text("anchor_id,tech,x,y,z\n" + "".join(
        f"A{i},uwb,{x},{y},{z}\n" for i, (x, y, z) in enumerate(anchors)))
    t = np.arange(0.0, 40.0, 0.1)
    path = np.column_stack([5 + 0.4 * t, 8 + 0.2 * t])
    i = np.arange(len(t)) % 4
    d = np.sqrt(np.sum((path - anchors[i, :2]) ** 2, axis=1) + (anchors[i, 2] - 1.0) ** 2) + rng.normal(0, 0.2, len(t))
    ranges = pd.DataFrame({"t": np.round(t, 2), "anchor_id": [f"A{k}" for k in i], "range_m": np.round(d, 4)})
    truth = pd.DataFrame({"t": np.round(t, 2), "x": path[:, 0], "y": path[:, 1]})
    truth.to_csv(folder / "truth.csv", index=False)
    return ranges


def test_unsorted_generic_ranges_lose_nothing_and_give_the_same_estimates(tmp_path):
    from wsnloc.estimators import registry
    from wsnloc.estimators.run_data import RunData
    from wsnloc.metrics.tracking import score

    rng = np.random.default_rng(14)
    ranges = _noisy_generic_run(tmp_path / "sorted", rng)
    ranges.to_csv(tmp_path / "sorted" / "ranges.csv", index=False)
    _copy(tmp_path / "sorted", tmp_path / "unsorted")
    shuffled = ranges.iloc[rng.permutation(len(ranges))]
    shuffled.to_csv(tmp_path / "unsorted" / "ranges.csv", index=False)
    campaign = Campaign.load(ROOT / "config" / "campaigns" / "cucudasluv.yaml")
    params = {"range_sigma_m": 0.2, "accel_sigma_mps2": 0.5}
    sorted_tables, _ = generic.ingest_run(tmp_path / "sorted", campaign)
    unsorted_tables, inventory = generic.ingest_run(tmp_path / "unsorted", campaign)
    assert len(unsorted_tables["ranges"]) == len(ranges) and len(unsorted_tables["quarantine"]) == 0
    assert inventory["ranges.csv"]["reordered"] > len(ranges) // 2
    columns = ["t", "anchor_id", "range_m"]
    pd.testing.assert_frame_equal(unsorted_tables["ranges"][columns], sorted_tables["ranges"][columns])
    a = score(registry.run("tracker", RunData(sorted_tables, campaign), params), sorted_tables["truth"])
    b = score(registry.run("tracker", RunData(unsorted_tables, campaign), params), unsorted_tables["truth"])
    pd.testing.assert_frame_equal(a, b)
    assert np.nanmedian(a["error_m"]) < 0.5


@pytest.fixture
def generic_dir(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "anchors.csv").write_text("anchor_id,tech,x,y\nA1,uwb,0,0\nA2,uwb,10,0\nA3,uwb,0,10\n")
    (folder / "ranges.csv").write_text("".join(["t,anchor_id,range_m\n"] + [f"{k / 10},A{k % 3 + 1},5.0\n"
                                                                            for k in range(80)]))
    return folder


def test_malformed_csv_row_is_quarantined_with_its_line(generic_dir):
    lines = _log_lines(generic_dir / "ranges.csv")
    lines[70] = "7.0,A1,5.0,9,9"                           # line 71, 5 fields
    lines[20] = "2.0,A2"                                   # line 21, 2 fields
    (generic_dir / "ranges.csv").write_text("\n".join(lines) + "\n")
    result, inventory = generic.ingest_run(generic_dir)
    q = result["quarantine"]
    assert q[["file", "line", "reason"]].values.tolist() == [
        ["ranges.csv", 21, "expected 3 fields (t,anchor_id,range_m), found 2"],
        ["ranges.csv", 71, "expected 3 fields (t,anchor_id,range_m), found 5"]]
    assert len(result["ranges"]) == 78 and inventory["ranges.csv"]["data_lines"] == 80


def test_csv_cut_mid_line_quarantines_the_partial_last_row(generic_dir):
    text = (generic_dir / "ranges.csv").read_text()
    (generic_dir / "ranges.csv").write_text(text[:-3])     # "7.9,A2,5" : the value cut short
    result, _ = generic.ingest_run(generic_dir)
    assert result["quarantine"][["line", "text"]].values.tolist() == [[81, "7.9,A2,5"]]
    assert "cut short" in result["quarantine"]["reason"].iloc[0]
    assert result["ranges"]["line"].max() == 80


def test_negative_and_non_finite_ranges_are_quarantined_naming_the_value(generic_dir):
    lines = _log_lines(generic_dir / "ranges.csv")
    lines[5], lines[6], lines[7] = "0.4,A2,-1.5", "0.5,A3,inf", "0.6,A1,"
    (generic_dir / "ranges.csv").write_text("\n".join(lines) + "\n")
    result, _ = generic.ingest_run(generic_dir)
    assert result["quarantine"].set_index("line")["reason"].to_dict() == {
        6: "range_m '-1.5' is negative", 7: "range_m 'inf' is not a finite number",
        8: "range_m '' is not a finite number"}


def test_a_zero_or_negative_stamp_among_unix_times_is_quarantined_and_the_run_still_tracks(generic_dir, tmp_path, capsys):
    """One row at t = 0 or t = -5 among Unix times stretched the run over 55 years (an epoch grid of
    3e9 periods: `wsnloc estimate` died allocating 26 GiB); now only those rows are quarantined."""
    lines = _log_lines(generic_dir / "ranges.csv")
    lines = [lines[0]] + [f"{1.7e9 + float(t)},{rest}" for t, rest in (line.split(",", 1) for line in lines[1:])]
    lines[10], lines[40] = "0,A1,5.0", "-5.0,A2,5.0"
    (generic_dir / "ranges.csv").write_text("\n".join(lines) + "\n")
    (generic_dir / "truth.csv").write_text(f"t,x,y\n{1.7e9},3,4\n{1.7e9 + 8},3,4\n")
    result, _ = generic.ingest_run(generic_dir)
    reasons = result["quarantine"].set_index("line")["reason"].to_dict()
    assert list(reasons) == [11, 41]
    assert reasons[11].startswith("t '0' is more than 86400 s from the median time of the file (1700000003.9")
    assert len(result["ranges"]) == 78 and result["ranges"]["t"].min() >= 1.7e9
    assert main(["estimate", "--format", "generic", str(generic_dir), "--out", str(tmp_path / "out"),
                 "--max-quarantine-share", "0.5", "--max-quarantine-share-per-file", "0.5"]) == 0
    assert "2 row(s) quarantined" in capsys.readouterr().out


def test_relative_times_near_zero_are_kept(generic_dir):
    """Times counted from the run's start (0, 0.1, ...) or slightly negative are not corrupt."""
    lines = _log_lines(generic_dir / "ranges.csv")
    lines[1] = "-5.0,A1,5.0"
    (generic_dir / "ranges.csv").write_text("\n".join(lines) + "\n")
    result, _ = generic.ingest_run(generic_dir)
    assert result["quarantine"].empty and result["ranges"]["t"].min() == -5.0


def test_duplicate_anchor_ids_are_refused(generic_dir):
    (generic_dir / "anchors.csv").write_text("anchor_id,tech,x,y\nA1,uwb,0,0\nA2,uwb,10,0\nA1,uwb,0,10\n")
    with pytest.raises(IngestError, match=r"anchors.csv: duplicate anchor id 'A1' \(lines 2, 4\)"):
        generic.ingest_run(generic_dir)


@pytest.mark.parametrize("name, text", [("ranges.csv", "t,anchor_id,range_m\n"),
                                        ("anchors.csv", "anchor_id,tech,x,y\n"), ("ranges.csv", "")])
def test_an_empty_required_table_is_refused(generic_dir, name, text):
    (generic_dir / name).write_text(text)
    with pytest.raises(IngestError, match=rf"{name}: (no data rows|empty file)"):
        generic.ingest_run(generic_dir)


def test_anchors_missing_from_the_anchors_table_are_counted(generic_dir, tmp_path, capsys):
    lines = _log_lines(generic_dir / "ranges.csv")
    for i in (1, 4, 2):                                   # rows of A1, A1, A2
        lines[i] = lines[i].replace(",A", ",B")
    (generic_dir / "ranges.csv").write_text("\n".join(lines) + "\n")
    assert main(["ingest", "--format", "generic", str(generic_dir), str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "2 row(s) of anchor 'B1', missing from the anchors table" in out
    assert "1 row(s) of anchor 'B2', missing from the anchors table" in out


def test_generic_cli_needs_no_campaign_and_keeps_2d_anchors(generic_dir, tmp_path, capsys):
    assert main(["ingest", "--format", "generic", str(generic_dir), str(tmp_path / "out")]) == 0
    anchors = pd.read_parquet(tmp_path / "out" / "anchors.parquet")
    assert anchors["z"].isna().all() and "quarantined share: 0.00%" in capsys.readouterr().out


# --- a real Cricket listener capture ---------------------------------------------------------

BEACONS = {"B1": "01:25:61:61:0b:00:00:42", "B3": "01:9a:5f:61:0b:00:00:a3", "B5": "01:e2:5f:61:0b:00:00:c1"}


def _capture():
    """A listener capture as a real listener prints it: its own space id (SP=ship), the
    campaign's beacon ids, RF-only records, and the damage of serial captures."""
    lines, t = [], 5000
    for k in range(60):
        beacon = list(BEACONS)[k % 3]
        t += 180
        if k % 10 == 9:
            lines.append(f"{t}\tVR=2.0,ID={BEACONS[beacon]},SP=ship,TS={t + 17}")        # RF only
        else:
            db = 150 + k
            lines.append(f"{t}\tVR=2.0,ID={BEACONS[beacon]},SP=ship,DB={db},DR={round(db / 100 / 343.4 * 1e6)},"
                         f"TM={t % 997},TS={t + 17}")
    damaged = {
        12: lambda s: s[: s.index(",TM=") + 1],                            # cut after a comma
        25: lambda s: s[: s.index(",DR=")],                                # cut before TS
        33: lambda s: s + s.split("\t")[1],                                # two records run together
        41: lambda s: re.sub(r"ID=[^,]*", "ID=", s).replace("SP=ship", "SP="),      # empty fields
        47: lambda s: s[:5],                                               # cut inside the host time
    }
    return [damaged[k](line) if k in damaged else line for k, line in enumerate(lines)], damaged


def test_a_listener_capture_alone_ingests_with_the_default_campaign(tmp_path, capsys, monkeypatch):
    lines, damaged = _capture()
    (tmp_path / "capture").mkdir()
    (tmp_path / "capture" / "listener.log").write_text("\n".join(lines) + "\n")
    monkeypatch.chdir(ROOT)                                # the default campaign: config/campaigns/cricket.yaml
    assert main(["ingest", "--format", "cricket", str(tmp_path / "capture"), str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "6 RF-only record(s) (no range)" in out
    ranges = pd.read_parquet(tmp_path / "out" / "ranges.parquet")
    quarantine = pd.read_parquet(tmp_path / "out" / "quarantine.parquet")
    assert quarantine["line"].tolist() == [k + 1 for k in sorted(damaged)]
    reasons = dict(zip(quarantine["line"], quarantine["reason"]))
    assert reasons[13] == "line cut short after a comma" and "cut short" in reasons[26]
    assert "run together" in reasons[34] and "no beacon" in reasons[42]
    assert len(ranges) == 60 - 6 - len(damaged) and set(ranges["anchor_id"]) == set(BEACONS)
    assert pd.read_parquet(tmp_path / "out" / "imu.parquet").empty


def test_a_capture_the_campaign_cannot_map_exits_nonzero(tmp_path, capsys):
    lines, _ = _capture()
    (tmp_path / "capture").mkdir()
    (tmp_path / "capture" / "listener.log").write_text("\n".join(line.replace("ID=01:", "ID=07:") for line in lines))
    assert main(["ingest", "--format", "cricket", "--campaign", str(CRICKET), str(tmp_path / "capture"),
                 str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "listener.log: 100.0% of its 60 records are quarantined" in err
    assert "unknown space id SP='…' and unknown beacon id '…'" in err


# --- random damage of each kind, per format ----------------------------------------------------

def _apply(draw, good: list[str], damage: dict, glitch=None):
    """Damage some of the `good` lines at random. `damage`: kind -> function(line, next line)
    giving the damaged text; `glitch` (when given): function(line, offset) moving a line's
    time far ahead, by offsets that decrease along the file (two glitches are never in
    order with each other), only where at least two intact lines follow (else a glitch is
    indistinguishable from the end of the log)."""
    kinds = draw(st.lists(st.sampled_from([None, None, None, *(["glitch"] if glitch else []), *damage]),
                          min_size=len(good), max_size=len(good)))
    intact_after, texts, bad = 0, [None] * len(good), set()
    for i in range(len(good) - 1, -1, -1):
        kind = kinds[i]
        if kind == "glitch" and intact_after < 2:
            kind = None
        if kind is None:
            texts[i] = good[i]
            intact_after += 1
        else:
            texts[i] = glitch(good[i], 10**9 + 1000 * (len(good) - i)) if kind == "glitch" \
                else damage[kind](good[i], good[(i + 1) % len(good)])
            bad.add(i)
    return texts, bad


UWB_ANCHORS = ["U01", "U02", "U05", "U12"]
UWB_DAMAGE = {
    "cut": lambda s, _: s[: len(s) - 2],
    "merged": lambda s, nxt: s + nxt,
    "unknown anchor": lambda s, _: s.replace(" U", " X", 1),
    "not a number": lambda s, _: s.replace(" 0", " 0x", 1) if s.endswith(" 0") else s + "?",
    "missing value": lambda s, _: " ".join(s.split()[:2] + s.split()[3:]),
}


@st.composite
def damaged_uwb(draw):
    n = draw(st.integers(3, 25))
    steps = draw(st.lists(st.integers(0, 40), min_size=n, max_size=n))
    t = 10000 + np.cumsum(steps)
    toa = draw(st.lists(st.integers(0, 300000), min_size=n, max_size=n))
    good = [f"{t[k]} {UWB_ANCHORS[k % 4]} {toa[k]} {k % 2 * 7}" for k in range(n)]
    texts, bad = _apply(draw, good, UWB_DAMAGE, lambda s, dt: f"{int(s.split()[0]) + dt} {s.split(' ', 1)[1]}")
    return good, texts, bad


@DAMAGE
@given(case=damaged_uwb())
def test_random_damage_in_uwb_log(campaign, tmp_path, case):
    good, texts, bad = case
    (tmp_path / "uwb.log").write_text("# newcom-uwb v1\n" + "".join(line + "\n" for line in texts))
    quarantine = Quarantine()
    ranges = newcom.parse_uwb(read_raw(tmp_path / "uwb.log", quarantine), campaign, quarantine)
    intact = [k for k in range(len(good)) if k not in bad]
    assert ranges["line"].tolist() == [k + 2 for k in intact]
    assert ranges["t"].tolist() == [int(good[k].split()[0]) / 1000 for k in intact]
    assert ranges["anchor_id"].tolist() == [good[k].split()[1] for k in intact]
    c = campaign.spec["speed_of_light_mps"]
    assert ranges["range_m"].tolist() == [c * int(good[k].split()[2]) * 1e-12 / 2 for k in intact]
    assert quarantine.frame()[["file", "line"]].values.tolist() == [["uwb.log", k + 2] for k in sorted(bad)]


ZIGBEE_DAMAGE = {
    "cut": lambda s, _: s[: len(s) - 3],
    "merged": lambda s, nxt: s + nxt,
    "count mismatch": lambda s, _: " ".join([*s.split()[:2], str(int(s.split()[2]) + 1), *s.split()[3:]]),
    "repeated anchor": lambda s, _: s.replace(" Z02:", " Z01:"),
    "unknown anchor": lambda s, _: s.replace(" Z01:", " Z71:"),
}


@st.composite
def damaged_zigbee(draw):
    n = draw(st.integers(3, 20))
    t = 10000 + 50 * np.arange(n)
    rssi = draw(st.lists(st.lists(st.integers(-99, -30), min_size=2, max_size=4), min_size=n, max_size=n))
    good = [f"{t[k]} {k} {len(r)} " + " ".join(f"Z0{j + 1}:{v}" for j, v in enumerate(r)) for k, r in enumerate(rssi)]
    texts, bad = _apply(draw, good, ZIGBEE_DAMAGE, lambda s, dt: f"{int(s.split()[0]) + dt} {s.split(' ', 1)[1]}")
    return good, texts, bad


@DAMAGE
@given(case=damaged_zigbee())
def test_random_damage_in_zigbee_log(campaign, tmp_path, case):
    good, texts, bad = case
    (tmp_path / "zigbee.log").write_text("# newcom-zigbee v1\n" + "".join(line + "\n" for line in texts))
    quarantine = Quarantine()
    rss = newcom.parse_zigbee(read_raw(tmp_path / "zigbee.log", quarantine), campaign, quarantine)
    expected = [(k + 2, int(good[k].split()[0]) / 1000, k, pair.split(":")[0], float(pair.split(":")[1]))
                for k in range(len(good)) if k not in bad for pair in good[k].split()[3:]]
    assert list(rss[["line", "t", "seq", "anchor_id", "rss_dbm"]].itertuples(index=False, name=None)) == expected
    assert quarantine.frame()[["file", "line"]].values.tolist() == [["zigbee.log", k + 2] for k in sorted(bad)]


@cache
def _cricket() -> Campaign:
    return Campaign.load(CRICKET)


def _speed_of_sound():
    return speed_of_sound(_cricket().section("radio", "cricket")["temperature_c"])


V2_DAMAGE = {
    "cut after a comma": lambda s, _: s[: s.index(",DR=") + 1],
    "cut before TS": lambda s, _: s[: s.index(",TS=")],
    "merged": lambda s, nxt: s + nxt.split("\t")[1],
    "empty fields": lambda s, _: s.replace(s[s.index("ID="): s.index(",DB=")], "ID=,SP="),
    "unknown beacon": lambda s, _: re.sub(r"SP=\w+", "SP=ship", s.replace("ID=01:", "ID=07:")),
    "lost digit": lambda s, _: s.replace(",DR=", ",DR=9"),
}


@st.composite
def damaged_listener(draw):
    n = draw(st.integers(3, 25))
    steps = draw(st.lists(st.integers(0, 400), min_size=n, max_size=n))
    t = 20000 + np.cumsum(steps)
    db = draw(st.lists(st.integers(30, 900), min_size=n, max_size=n))
    own_space = draw(st.lists(st.booleans(), min_size=n, max_size=n))     # SP=ship: mapped by ID
    c = _speed_of_sound()
    good = [f"{t[k]}\tVR=2.0,ID={BEACONS[list(BEACONS)[k % 3]]},SP={'ship' if own_space[k] else list(BEACONS)[k % 3]},"
            f"DB={db[k]},"
            f"DR={round(db[k] / 100 / c * 1e6)},TM={k},TS={t[k] + 5}" for k in range(n)]
    texts, bad = _apply(draw, good, V2_DAMAGE, lambda s, dt: f"{int(s.split(chr(9))[0]) + dt}\t{s.split(chr(9))[1]}")
    return good, texts, bad


@DAMAGE
@given(case=damaged_listener())
def test_random_damage_in_listener_log(tmp_path, case):
    good, texts, bad = case
    campaign = _cricket()
    run = tmp_path / "run"
    run.mkdir(exist_ok=True)
    (run / "listener.log").write_text("".join(line + "\n" for line in texts))
    result, inventory = cricket.ingest_run(run, campaign)
    intact = [k for k in range(len(good)) if k not in bad]
    ranges = result["ranges"]
    assert ranges["line"].tolist() == [k + 1 for k in intact]
    assert ranges["t"].tolist() == [int(good[k].split("\t")[0]) / 1000 for k in intact]
    assert ranges["anchor_id"].tolist() == [list(BEACONS)[k % 3] for k in intact]
    dr_us = [int(good[k].split(",DR=")[1].split(",")[0]) for k in intact]
    assert ranges["range_m"].tolist() == [d * 1e-6 * _speed_of_sound() for d in dr_us]
    assert result["quarantine"]["line"].tolist() == [k + 1 for k in sorted(bad)]
    assert set(result["quarantine"]["file"]) <= {"listener.log"} and set(inventory) == {"listener.log"}


GENERIC_DAMAGE = {
    "extra field": lambda s, _: s + ",9",
    "missing field": lambda s, _: s.rsplit(",", 1)[0],
    "merged": lambda s, nxt: s + nxt,
    "not finite": lambda s, _: s.rsplit(",", 1)[0] + ",nan",
    "negative": lambda s, _: s.rsplit(",", 1)[0] + ",-" + s.rsplit(",", 1)[1],
    "unknown anchor": lambda s, _: s.replace(",A", ",Z"),
    "empty anchor": lambda s, _: s.replace(s.split(",")[1], ""),
}


@st.composite
def damaged_ranges_csv(draw):
    n = draw(st.integers(2, 30))
    t = draw(st.lists(st.integers(0, 5000) | st.just(100), min_size=n, max_size=n))   # in any order
    r = draw(st.lists(st.integers(1, 99999) | st.just(1000), min_size=n, max_size=n))  # repeats likely
    good = [f"{t[k] / 100},A{k % 3 + 1},{r[k] / 1000}" for k in range(n)]
    texts, bad = _apply(draw, good, GENERIC_DAMAGE)
    cut_last = draw(st.booleans())
    return good, texts, bad, cut_last


@DAMAGE
@given(case=damaged_ranges_csv())
@example(case=(["0.0,A1,0.001", "0.0,A2,0.001", "0.0,A3,0.001", "0.0,A1,0.001"],) * 2 + (set(), False))
def test_random_damage_in_a_generic_table(tmp_path, case):
    good, texts, bad, cut_last = case
    run = tmp_path / "run"
    run.mkdir(exist_ok=True)
    (run / "anchors.csv").write_text("anchor_id,tech,x,y\nA1,uwb,0,0\nA2,uwb,10,0\nA3,uwb,0,10\n")
    text = "t,anchor_id,range_m\n" + "".join(line + "\n" for line in texts)
    if cut_last:                                          # the copy stopped inside the last line
        text = text[:-2]
        bad = bad | {len(good) - 1}
    (run / "ranges.csv").write_text(text)
    result, inventory = generic.ingest_run(run)
    first_seen, repeats = {}, {}                           # a usable row equal to an earlier one is a repeat
    for k in range(len(good)):
        if k not in bad and first_seen.setdefault(good[k], k) != k:
            repeats[k + 2] = f"a repeat of line {first_seen[good[k]] + 2} (every value equal)"
    bad = bad | {line - 2 for line in repeats}
    intact = sorted((k for k in range(len(good)) if k not in bad), key=lambda k: float(good[k].split(",")[0]))
    ranges = result["ranges"]
    assert ranges["line"].tolist() == [k + 2 for k in intact]
    assert ranges["t"].tolist() == [float(good[k].split(",")[0]) for k in intact]
    assert ranges["anchor_id"].tolist() == [good[k].split(",")[1] for k in intact]
    assert ranges["range_m"].tolist() == [float(good[k].split(",")[2]) for k in intact]
    q = result["quarantine"]
    assert q["file"].eq("ranges.csv").all() and q["line"].tolist() == [k + 2 for k in sorted(bad)]
    assert {line: reason for line, reason in zip(q["line"], q["reason"]) if line in repeats} == repeats
    assert inventory["ranges.csv"]["data_lines"] == len(good)
