"""The wsnloc command line: exit codes and what it prints."""


from wsnloc.cli import main

from conftest import NEWCOM, ROOT


def test_ingest_prints_counts(simulated_run, tmp_path, capsys):
    assert main(["ingest", "--format", "newcom", "--campaign", str(NEWCOM), str(simulated_run), str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "uwb.log" in out and "quarantined share: 0.00%" in out
    assert (tmp_path / "ranges.parquet").exists()


def test_ingest_unreadable_input_exits_nonzero(tmp_path, capsys):
    assert main(["ingest", "--format", "newcom", "--campaign", str(NEWCOM), str(tmp_path / "none"), str(tmp_path)]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_simulate_then_validate(tmp_path, capsys, monkeypatch):
    assert main(["simulate", "--campaign", str(NEWCOM), "--scenario", "variable", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "run-01" / "imu.log").exists()
    monkeypatch.chdir(ROOT)
    assert main(["validate-config"]) == 0
    bad = tmp_path / "bad.yaml"
    bad.write_text("runs: -1\ndatasets: {}\n")
    assert main(["validate-config", str(bad)]) == 2
    assert "config key 'runs'" in capsys.readouterr().err


def test_unknown_scenario_is_named(tmp_path, capsys):
    assert main(["simulate", "--campaign", str(NEWCOM), "--scenario", "sprint", "--out", str(tmp_path)]) == 2
    assert "scenarios.sprint" in capsys.readouterr().err


def test_validate_config_names_a_subset_the_campaign_lacks(tmp_path, capsys, monkeypatch):
    import yaml

    monkeypatch.chdir(ROOT)
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    config["experiments"]["paper_c"]["table_1_subset"] = "7: B1..B7"
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(config))
    assert main(["validate-config", str(tmp_path / "config.yaml")]) == 2
    assert ("config key 'experiments.paper_c.table_1_subset': '7: B1..B7' is not an anchor subset of "
            "config/campaigns/cricket.yaml") in capsys.readouterr().err


def test_a_simulated_runs_scenario_gives_the_campaign_its_heights(tmp_path):
    """`wsnloc ingest / estimate --format newcom` on a run of a 3-D scenario reads the campaign as
    that scenario sees it (the scenario its meta.yaml names): the flight's anchor heights, not the
    planar campaign's."""
    import argparse

    from wsnloc.campaign import Campaign
    from wsnloc.cli import _ingest_campaign

    source = str(ROOT / "config" / "campaigns" / "newcom.yaml")
    args = argparse.Namespace(format="newcom", campaign=source, run_dir=str(tmp_path))
    planar = _ingest_campaign(args)                       # no meta.yaml: the campaign as it is
    (tmp_path / "meta.yaml").write_text("scenario: flight\n")
    flight = _ingest_campaign(args)
    expected = Campaign.load(source).for_scenario("flight")
    assert flight.anchors["z"].equals(expected.anchors["z"]) and flight.anchors["z"].notna().sum() == 12   # UWB heights
    assert planar.anchors["z"].isna().all()


def test_estimate_tracks_in_3d_where_the_campaign_declares_varying_heights():
    """estimators.auto.dimensions_for: 3 on a declared height profile (the flight), 2 on the planar
    campaign, a height that varies by less than VARYING_HEIGHT_M, or an explicit setting."""
    from wsnloc.campaign import Campaign
    from wsnloc.estimators.auto import VARYING_HEIGHT_M, dimensions_for
    from wsnloc.geometry.path import Path as TagPath

    campaign = Campaign.load(str(ROOT / "config" / "campaigns" / "newcom.yaml"))
    flight = campaign.for_scenario("flight")
    p = {"dimensions": 2, "motion": "pv"}
    assert dimensions_for(flight, p, set())["dimensions"] == 3
    assert dimensions_for(flight, p, {"dimensions"}) == p and dimensions_for(campaign, p, set()) == p
    assert dimensions_for(flight, {"motion": "pv"}, set()) == {"motion": "pv"}      # no such parameter
    for planar_only in ("pva", "odometry"):                                          # no 3-D state
        assert dimensions_for(flight, dict(p, motion=planar_only), {"motion"})["dimensions"] == 2
    flight.path = TagPath(flight.path.points, flight.path.corner_radius, [[0.0, 1.0], [10.0, 1.0 + VARYING_HEIGHT_M / 2]])
    assert dimensions_for(flight, p, set()) == p
