"""The report: values from logs and config are escaped; one number formatter; honest data
labels and sections; study cells show their settings; the browser check catches problems."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from wsnloc import results
from wsnloc.io.newcom import ingest_run
from wsnloc.metrics.data_quality import summarize
from wsnloc.report.browser_check import browser_available, check_report
from wsnloc.report.render import build_context, data_banner, fmt_number, render_pages

from conftest import ROOT

TEMPLATES = ROOT / "workflow" / "templates"

EVIL = "<script>alert(1)</script>"


def test_log_and_config_text_is_escaped(campaign, simulated_run):
    tables, inventory = ingest_run(simulated_run, campaign)
    summary, rows, _ = summarize({"run-01": tables}, {}, campaign, "newcom/constant")
    summary["inventory"] = {"run-01": inventory}
    summary["per_anchor"][0]["anchor_id"] = EVIL
    summary["quarantine_examples"] = [{"run": "run-01", "file": "uwb.log", "line": 3, "text": f"12500 {EVIL} 1 0",
                                       "reason": f"unknown anchor '{EVIL}'"}]
    config = {"runs": 1, "seed": 1, "report": {"title": f"t {EVIL}"},
              "datasets": {"newcom": {"format": "newcom", "campaign": "c.yaml", "source": "simulate",
                                      "scenarios": ["constant"], "raw_dir": EVIL}}}
    context = build_context(config, [summary], results.frame(rows), {}, {})
    pages = render_pages(TEMPLATES, context)
    html = "".join(pages.values())
    assert EVIL not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in pages["index.html"]           # the title
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in pages["pages/data-newcom.html"]   # anchor id, log line
    assert set(pages) == {"index.html", "pages/data-newcom.html", "pages/provenance.html"}


def test_one_formatter_for_every_number():
    assert [fmt_number(v) for v in (0.03188, 1.2345, 207.4, 12345.6, 0.0, 20, None, np.nan)] == [
        "0.0319", "1.23", "207", "12346", "0", "20", "", ""]
    assert fmt_number(6.98e40) == "6.98e40" and fmt_number(6.98e40, diverged=True) == "diverged"
    assert fmt_number(math.inf) == "not finite" and fmt_number(0.1234, signed=True) == "+0.123"
    assert fmt_number(0.5, unit="m") == "0.500\u2009m" and fmt_number(3.1e-5) == "3.10e-5"
    assert all(len(fmt_number(10.0 ** k * 1.2345)) <= 13 for k in range(-12, 60))


def test_banner_says_whether_data_are_simulated_synthetic_or_measured():
    config = {"runs": 3, "seed": 1, "datasets": {
        "a": {"source": "simulate"}, "b": {"source": "logs", "raw_dir": "raw/b", "kind": "synthetic"},
        "c": {"source": "logs", "raw_dir": "raw/c"}}}
    a, b, c = data_banner(config)
    assert a.startswith("a: SIMULATED") and b == "b: SYNTHETIC (not measured) logs from raw/b."
    assert c == "c: MEASURED logs from raw/c."


def test_data_page_shows_imu_rss_and_walls_only_where_the_dataset_has_them(campaign, simulated_run, tmp_path):
    tables, inventory = ingest_run(simulated_run, campaign)
    summary, rows, _ = summarize({"run-01": tables}, {}, campaign, "newcom/constant")
    for run in summary["per_run"]:
        run.update(imu=0, rss=0)
    bare = tmp_path / "bare.yaml"
    bare.write_text("name: bare\n")          # a campaign file without walls
    config = {"runs": 1, "seed": 1, "report": {"title": "t"},
              "datasets": {"newcom": {"format": "newcom", "campaign": str(bare), "source": "logs", "kind": "synthetic",
                                      "scenarios": ["constant"], "raw_dir": "r"}}}
    written = []
    figures = {"newcom/constant": {"rss_distance": b"rss", "imu_resampling": b"imu", "range_error": b"range"}}
    no_rss = results.frame(rows).query("table != 'RSS path-loss fit'")
    context = build_context(config, [summary], no_rss, figures, {}, lambda png: written.append(png) or "f.png")
    assert written == [b"range"]       # no figure is written that the page does not show (orphan placeholders)
    assert context["datasets"][0]["has"] == {"imu": False, "rss": False, "walls": False}
    page = render_pages(TEMPLATES, context)["pages/data-newcom.html"]
    assert "IMU resampling" not in page and "IMU samples" not in page and "RSS samples" not in page
    assert "SYNTHETIC (not measured)" in page and "The floor plan has no walls" in page


def test_study_page_shows_each_cells_settings_not_dict_reprs():
    from wsnloc.report.sections import study_section

    spec = {"scenarios": ["newcom/constant"], "runs": 5,
            "estimators": {"tracker": {}, "plain": {"estimator": "ekf", "gate_probability": 0.0}},
            "overrides": {"newcom": {"max_range_m": 50.0, "plain": {"range_sigma_m": 0.2}}}}
    rows = [results.row_over_runs([0.2, 0.21, 0.22, 0.2, 0.19], experiment="study:s", table="all", row=cell,
                                  column=stat, scenario="newcom/constant", metric=f"{stat}_m")
            for cell in spec["estimators"] for stat in ("median", "p75", "rmse")]
    section = study_section(results.frame(rows), "s", spec, {}, ["median", "p75", "rmse"])
    settings = {e["cell"]: e["settings"][0] for e in section["estimators"]}
    assert settings["tracker"] == ["max_range_m = 50"]
    assert sorted(settings["plain"]) == ["gate_probability = 0", "max_range_m = 50", "range_sigma_m = 0.2"]
    context = {"title": "t", "banner": [], "datasets": [], "papers": [], "studies": [section], "summary": [],
               "experiments": [], "provenance": {"built": "", "git_commit": "", "config_hash": "", "packages": {},
                                                 "config_yaml": "", "checksums": []}}
    pages = render_pages(TEMPLATES, context)
    study = pages["pages/study-s.html"]
    assert "max_range_m = 50" in study and "registry defaults" not in study and "{&#39;" not in study
    assert "0.204 <span" in study and "mean over 5 runs with 95% interval" in study
    assert 'href="pages/study-s.html"' in pages["index.html"]


needs_browser = pytest.mark.skipif(browser_available() is not None,
                                   reason=f"headless browser check unavailable: {browser_available()}")


@needs_browser
def test_browser_check_catches_external_requests_and_broken_images(tmp_path):
    page = tmp_path / "bad.html"
    page.write_text('<html><body><img alt="remote" src="http://127.0.0.1:9/x.png">'
                    '<img alt="broken" src="data:image/png;base64,AAAA"><script>undefinedCall()</script></body></html>')
    problems = check_report(page, sections=("paper-A",))["problems"]
    text = "\n".join(problems)
    assert "network request beyond the report: http://127.0.0.1:9/x.png" in text
    assert "image does not decode: 'remote'" in text and "image does not decode: 'broken'" in text
    assert "console error" in text and "section paper-A is missing" in text


def test_trajectory_panels_frame_the_truth_not_a_diverged_estimate():
    import pandas as pd

    from wsnloc.report.figures import trajectories, trajectory_frame

    truth = pd.DataFrame({"t": [0.0, 1.0, 2.0], "x": [0.0, 10.0, 10.0], "y": [0.0, 0.0, 4.0]})
    assert trajectory_frame(truth) == (-5.0, 15.0, -5.0, 9.0)      # half of the larger side (10 m) each way
    diverged = pd.DataFrame({"t": [0.0, 1.0], "x": [1.0, 3.0e4], "y": [1.0, -3.0e4]})
    assert trajectories({"run": (truth, {"pf": diverged})})[:4] == b"\x89PNG"


def test_counts_agree_with_their_noun():
    """'1 cell' / '1 run', never '1 cells'; no template prints a bare count before a plural noun."""
    from wsnloc.report.render import counted
    assert (counted(1, "cell"), counted(2, "run"), counted(0, "run")) == ("1 cell", "2 runs", "0 runs")
    templates = Path(__file__).parents[1] / "workflow" / "templates"
    bare = [(f.name, line) for f in templates.glob("*.j2") for line in f.read_text().splitlines()
            if re.search(r"(length|runs) }} (runs|cells)\b", line)]
    assert not bare, bare


def test_error_and_bound_plots_share_the_runs_time_origin(monkeypatch):
    """The error over time and sqrt(PCRB) of one run are drawn on the same clock (the run's t, s)."""
    import matplotlib.axes
    import pandas as pd

    from wsnloc.report import bound_figures, figures
    drawn = []
    plot = matplotlib.axes.Axes.plot
    monkeypatch.setattr(matplotlib.axes.Axes, "plot",
                        lambda self, x, *a, **k: drawn.append(np.asarray(x, dtype=float)) or plot(self, x, *a, **k))
    t = np.arange(10.0, 105.0, 0.5)
    figures.error_over_time({"run": {"tracker": pd.DataFrame({"t": t, "error_m": np.ones_like(t)})}})
    bound_figures.pcrb_vs_rmse(t, {"tracker": np.ones_like(t)}, 0.5 * np.ones_like(t), "PV", "run")
    assert drawn and all(x[0] == t[0] and x[-1] == t[-1] for x in drawn), [(x[0], x[-1]) for x in drawn]


def test_study_says_why_rmse_exceeds_the_bound_from_the_scenarios_data():
    """The sentence under a study's table: the ratio, the ANEES verdict and the NLOS share and
    excess of that scenario's data summary (not typed numbers); no sentence for a cell at its bound."""
    import pandas as pd

    from wsnloc.report.explanations import Numbers, study_bound_whys

    def cell(ratio, anees):
        return {"efficiency": {"value": ratio}, "gated": {"value": 0.15},
                "anees": {"value": anees, "band_low": 1.5, "band_high": 2.6,
                          "verdict": "optimistic" if anees > 2.6 else "consistent"}}

    study = {"tables": [{"scenarios": ["newcom/tdoa", "newcom/flight"],
                         "rows": [{"label": "tracker", "cells": [cell(2.23, 7.2), cell(1.0, 2.0)]}]}]}
    pooled = {"LOS": {"n": 300, "median": 0.07, "bias": 0.01}, "NLOS": {"n": 100, "bias": 1.31, "p95": 5.6}}
    summaries = {label: {"range_error_pooled": pooled} for label in ("newcom/tdoa", "newcom/flight")}
    study["tables"][0]["subset"] = "all"
    whys = study_bound_whys(Numbers(pd.DataFrame(), summaries), study)
    assert len(whys) == 2, whys          # the tdoa scenario, then where the own-model ratio is shown
    assert whys[0].startswith("newcom/tdoa (subset all): RMSE / sqrt(PCRB) tracker 2.23, ANEES 7.20 optimistic "
                              "(band [1.50, 2.60]), gate rejected 15%")
    assert "25% of the valid ranges are NLOS" in whys[0] and "median excess of 1.31 m" in whys[0]
    assert "range differences" in whys[0] and "test_3d_flight_rmse_is_within_1_5_of_the_pcrb" in whys[1]
