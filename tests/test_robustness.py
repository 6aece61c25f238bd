"""Robustness: arbitrary bytes in every raw format never crash ingest (the line is parsed
or quarantined; an unusable file gives a clear IngestError), and NaN, inf, negative and
huge measurements never crash an estimator."""

import shutil

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wsnloc.campaign import Campaign
from wsnloc.errors import IngestError
from wsnloc.estimators import registry
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import paper_a, paper_d
from wsnloc.io import cricket, generic, newcom

from conftest import ROOT
from test_ekf import RSS_MODEL as RSS_MODEL_A, SPEC_A
from test_paper_d import LABEL, RSS_MODEL as RSS_MODEL_D, SPEC as SPEC_D

FUZZ = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])
junk = st.binary(max_size=400)


def _with_file(src, tmp_path, name, data: bytes):
    target = tmp_path / "run"
    if target.exists():
        shutil.rmtree(target)
    shutil.copytree(src, target)
    with (target / name).open("ab") as handle:
        handle.write(b"\n" + data)
    return target


@FUZZ
@given(name=st.sampled_from(["uwb.log", "zigbee.log", "imu.log", "truth.log"]), data=junk)
def test_arbitrary_bytes_in_newcom_logs(campaign, simulated_run, tmp_path, name, data):
    run = _with_file(simulated_run, tmp_path, name, data)
    result, inventory = newcom.ingest_run(run, campaign)
    lines = data.count(b"\n") + 1
    assert inventory[name]["quarantined"] <= lines
    assert set(result) == {"ranges", "rss", "tdoa", "imu", "truth", "anchors", "quarantine"}


@FUZZ
@given(data=junk)
def test_arbitrary_bytes_replacing_a_whole_log(campaign, simulated_run, tmp_path, data):
    run = _with_file(simulated_run, tmp_path, "uwb.log", b"")
    (run / "imu.log").write_bytes(data)
    try:
        newcom.ingest_run(run, campaign)
    except IngestError as exc:          # e.g. no scale-factor header: a clear, named error
        assert "imu.log" in str(exc)


@pytest.fixture(scope="module")
def cricket_campaign():
    return Campaign.load(ROOT / "config" / "campaigns" / "cricket.yaml")


@FUZZ
@given(data=junk)
def test_arbitrary_bytes_in_a_listener_log(cricket_campaign, tmp_path, data):
    run = tmp_path / "run"
    run.mkdir(exist_ok=True)
    (run / "listener.log").write_bytes(data)
    (run / "imu.log").write_text("# cricket-imu v1\n# accel_lsb_per_g=1024 gyro_lsb_per_dps=131.072\n")
    (run / "truth.log").write_text("")
    result, inventory = cricket.ingest_run(run, cricket_campaign)
    assert len(result["ranges"]) + inventory["listener.log"]["rf_only"] + inventory["listener.log"]["quarantined"] \
        == inventory["listener.log"]["data_lines"]


@FUZZ
@given(data=junk)
def test_arbitrary_bytes_in_a_generic_table(tmp_path, data):
    generic_campaign = Campaign.load(ROOT / "config" / "campaigns" / "cucudasluv.yaml")
    run = tmp_path / "run"
    run.mkdir(exist_ok=True)
    (run / "anchors.csv").write_text("anchor_id,tech,x,y\nA1,uwb,0,0\n")
    (run / "ranges.csv").write_bytes(b"t,anchor_id,range_m\n" + data)
    try:
        result, inventory = generic.ingest_run(run, generic_campaign)
    except IngestError as exc:
        assert "ranges.csv" in str(exc)
    else:
        assert len(result["ranges"]) + inventory["ranges.csv"]["quarantined"] == inventory["ranges.csv"]["data_lines"]


BAD_VALUES = st.sampled_from([np.nan, np.inf, -np.inf, -5.0, 0.0, 1e300, 1e-300])


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                 HealthCheck.too_slow])
@given(values=st.lists(BAD_VALUES, min_size=1, max_size=30), rss=st.lists(BAD_VALUES, min_size=1, max_size=30))
def test_bad_measurements_never_crash_the_estimators(campaign, simulated_run, values, rss):
    tables, _ = newcom.ingest_run(simulated_run, campaign)
    ranges, rss_table = tables["ranges"].copy(), tables["rss"].copy()
    ranges.loc[ranges.index[: len(values)], "range_m"] = values
    rss_table.loc[rss_table.index[: len(rss)], "rss_dbm"] = rss
    tables = dict(tables, ranges=ranges, rss=rss_table)
    data = RunData(tables, campaign, RSS_MODEL_D)
    estimates = paper_d.run(data, SPEC_D, LABEL)
    assert np.isfinite(estimates["error_m"]).mean() > 0.9
    a = paper_a.run(RunData(tables, campaign, RSS_MODEL_A), SPEC_A, LABEL)
    assert np.isfinite(a[["x", "y"]].to_numpy()).all()
    fixes = registry.run("minmax", data, {"anchors": "UWB=10", "max_range_m": 50.0})
    assert fixes["t"].is_monotonic_increasing


def test_unfiltered_ranges_with_nan_are_dropped(campaign, simulated_run):
    tables, _ = newcom.ingest_run(simulated_run, campaign)
    ranges = tables["ranges"].copy()
    ranges.loc[ranges.index[:5], "range_m"] = np.nan
    spec = {**SPEC_D, "parameters": {**SPEC_D["parameters"], "preliminary_filter": False}}
    raw = paper_d.run(RunData(dict(tables, ranges=ranges), campaign, RSS_MODEL_D), spec, LABEL)
    assert np.isfinite(raw["x"]).mean() > 0.9
