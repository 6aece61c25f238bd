"""Browser check: empty intervals "[, ]" and figures whose texts overlap, on small pages."""

import base64
import io

import matplotlib.pyplot as plt
import pytest
from PIL import Image

from wsnloc.report import browser_check
from wsnloc.report.browser_check import browser_available, check_page_content, check_report
from wsnloc.report.figures import OVERLAPS_KEY, text_overlaps, to_png


def overlapping_figure() -> bytes:
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.plot([0, 10], [0, 5])
    ax.set_title("RMSE against speed")
    ax.text(2.0, 2.0, "Min-Max UWB", fontsize=12)
    ax.text(2.3, 2.05, "multilateration", fontsize=12)       # drawn over the first label
    return to_png(fig)


def clean_figure() -> bytes:
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.plot([0, 10], [0, 5], label="track")
    ax.set_xlim(0.3, 9.7)                 # the locator's ticks at 0 and 10 fall outside the view
    ax.set(title="RMSE against speed", xlabel="speed (m/s)", ylabel="RMSE (m)")
    ax.legend()
    return to_png(fig)


def page(tmp_path, body: str):
    path = tmp_path / "page.html"
    path.write_text(f"<html><head><style>p {{}}</style></head><body>{body}</body></html>", encoding="utf-8")
    return path


def img(png: bytes, alt: str) -> str:
    return f'<img alt="{alt}" src="data:image/png;base64,{base64.b64encode(png).decode()}">'


def test_to_png_records_overlapping_texts():
    assert Image.open(io.BytesIO(overlapping_figure())).text[OVERLAPS_KEY] == '[["Min-Max UWB", "multilateration"]]'
    assert Image.open(io.BytesIO(clean_figure())).text[OVERLAPS_KEY] == "[]"


def test_overlap_is_measured_on_rendered_boxes():
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.set_axis_off()
    ax.text(0.1, 0.5, "left", transform=ax.transAxes)
    ax.text(0.8, 0.5, "right", transform=ax.transAxes)
    assert text_overlaps(fig) == []
    ax.texts[1].set_x(0.12)                                   # now on top of "left"
    assert text_overlaps(fig) == [("left", "right")]
    plt.close(fig)


def test_page_check_names_overlapping_figure_and_empty_interval(tmp_path):
    bad = page(tmp_path, f"<h2>Paper D</h2>{img(clean_figure(), 'clean')}{img(overlapping_figure(), 'Fig. 3 of D')}"
                         "<td>0.41 <span>[</span>, <span>]</span></td>")
    problems = check_page_content(bad)
    assert problems[0].startswith("empty interval '[, ]' in the page text: ...Paper D 0.41 [ , ]")
    assert problems[1:] == ["figure 'Fig. 3 of D': text 'Min-Max UWB' overlaps 'multilateration'"]
    good = page(tmp_path, f"<p>0.41 [0.38, 0.44]</p>{img(clean_figure(), 'clean')}<script>x = '[, ]'</script>")
    assert check_page_content(good) == []


def test_figure_without_overlap_record_fails(tmp_path):
    buffer = io.BytesIO()
    Image.new("RGB", (4, 4)).save(buffer, format="png")
    problems = check_page_content(page(tmp_path, img(buffer.getvalue(), "hand-made")))
    assert problems == ["figure 'hand-made' has no text-overlap record (not saved by figures.to_png)"]


@pytest.mark.skipif(browser_available() is None, reason="with a browser the CLI runs the full check")
def test_cli_without_browser_still_checks_text_and_figures(tmp_path, capsys):
    assert browser_check.main([str(page(tmp_path, img(overlapping_figure(), "fig")))]) == 1
    assert "text 'Min-Max UWB' overlaps 'multilateration'" in capsys.readouterr().err
    assert browser_check.main([str(page(tmp_path, img(clean_figure(), "fig")))]) == 2


@pytest.mark.skipif(browser_available() is not None, reason=f"headless browser unavailable: {browser_available()}")
def test_browser_check_reports_overlaps_and_empty_intervals(tmp_path):
    bad = page(tmp_path, f"{img(overlapping_figure(), 'Fig. 3 of D')}<p>0.41 [, ]</p>")
    problems = check_report(bad, sections=())["problems"]
    assert "page.html: figure 'Fig. 3 of D': text 'Min-Max UWB' overlaps 'multilateration'" in problems
    assert any(p.startswith("page.html: empty interval") for p in problems)


@pytest.mark.skipif(browser_available() is not None, reason=f"headless browser unavailable: {browser_available()}")
def test_browser_check_follows_the_summary_to_every_page(tmp_path):
    """A report of a summary and pages/: broken fragments, unlinked pages, long numbers and
    overlapping figure files are found on the pages the summary links to."""
    (tmp_path / "pages" / "figures").mkdir(parents=True)
    (tmp_path / "pages" / "figures" / "bad.png").write_bytes(overlapping_figure())
    (tmp_path / "index.html").write_text('<html><body><a href="pages/study-a.html#results">a</a>'
                                         '<a href="pages/study-a.html#nowhere">b</a><a href="pages/gone.html">c</a></body></html>')
    (tmp_path / "pages" / "study-a.html").write_text(
        '<html><body><h2 id="results">a</h2><img alt="cdf" src="figures/bad.png">'
        '<p>ANEES 69811100000000002039197455862640538550272</p><a href="../index.html">back</a></body></html>')
    (tmp_path / "pages" / "orphan.html").write_text("<html><body>not linked</body></html>")
    outcome = check_report(tmp_path / "index.html", sections=(), screenshots=tmp_path / "shots")
    problems = "\n".join(outcome["problems"])
    assert outcome["pages"] == ["index.html", "pages/study-a.html"]
    assert "index.html: link file://" in problems and "no element with id 'nowhere'" in problems
    assert "pages/gone.html reaches no file" in problems and "page pages/orphan.html is not linked from the summary" in problems
    assert "pages/study-a.html: figure 'cdf': text 'Min-Max UWB' overlaps 'multilateration'" in problems
    assert "pages/study-a.html: number of 41 digits" in problems
    assert "network request" not in problems and (tmp_path / "shots" / "pages_study-a.png").is_file()


@pytest.mark.skipif(browser_available() is not None, reason=f"headless browser unavailable: {browser_available()}")
def test_browser_check_reports_a_fit_table_that_scrolls_sideways(tmp_path):
    """A box of class `fit` (the sensitivity tables) wider than the page is a problem named by its
    heading; the same table in a `.wide` box (meant to scroll) and a narrow `.fit` one are not."""
    style = "<style>.fit, .wide { max-width: 100%; overflow-x: auto; }</style>"
    row = "<table><tr>" + "<td style='min-width: 200px'>x</td>" * 12 + "</tr></table>"
    bad = page(tmp_path, f"{style}<h4>Sensitivity</h4><div class='fit'>{row}</div>"
                         f"<div class='wide'>{row}</div><div class='fit'><table><tr><td>y</td></tr></table></div>")
    problems = check_report(bad, sections=())["problems"]
    assert problems == ["page.html: a table that must fit the page width scrolls sideways: 'Sensitivity'"], problems
