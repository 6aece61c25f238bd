"""The report: values from logs and config are escaped; the browser check catches problems."""

import pytest

from wsnloc import results
from wsnloc.io.newcom import ingest_run
from wsnloc.metrics.data_quality import summarize
from wsnloc.report.browser_check import browser_available, check_report
from wsnloc.report.render import build_context, render

from conftest import ROOT

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
    context["papers"], context["studies"] = [], []
    html = render(ROOT / "workflow" / "templates" / "report.html.j2", context)
    assert EVIL not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html


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
