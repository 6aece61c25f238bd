"""Load the built report in headless Chromium and check what a reader would see.

Checks: no console errors; no network request other than the report file itself (and
its inline data: images); every image decodes; every paper section holds its tables.
Saves a screenshot. Needs Debian's `chromium` and `chromium-driver` and the `selenium`
package; `python -m wsnloc.report.browser_check reports/index.html --screenshot X.png`.

Two checks need no browser and also run without one: no empty interval "[, ]" in the
page's text, and no figure whose texts overlap (each embedded PNG carries the overlapping
pairs found when it was saved, in the text chunk wsnloc.report.figures.OVERLAPS_KEY).
"""

from __future__ import annotations

import argparse
import base64
import binascii
import io
import json
import re
import shutil
import sys
import tempfile
from html.parser import HTMLParser
from pathlib import Path

from PIL import Image, UnidentifiedImageError

from wsnloc.report.figures import OVERLAPS_KEY

CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--window-size=1280,2000"]


EMPTY_INTERVAL = re.compile(r"\[\s*,\s*\]")
PNG_DATA_URI = "data:image/png;base64,"


def empty_interval_problems(page_text: str) -> list[str]:
    """One problem per empty interval "[, ]" in the page text, quoting its surroundings."""
    problems = []
    for match in EMPTY_INTERVAL.finditer(page_text):
        context = " ".join(page_text[max(0, match.start() - 60):match.end() + 20].split())
        problems.append(f"empty interval '[, ]' in the page text: ...{context}...")
    return problems


def figure_overlap_problems(images) -> list[str]:
    """Problems of the embedded PNG figures, given as (src, alt, title) triples.

    A figure fails when its OVERLAPS_KEY chunk lists overlapping texts, or when it has no such
    chunk (it was not saved by wsnloc.report.figures.to_png, so nothing checked it).
    Images that are not inline PNGs are left to the other checks.
    """
    problems = []
    for number, (src, alt, title) in enumerate(images, start=1):
        if not src.startswith(PNG_DATA_URI):
            continue
        name = alt or title or f"image {number}"
        try:
            text = Image.open(io.BytesIO(base64.b64decode(src[len(PNG_DATA_URI):], validate=True))).text
        except (binascii.Error, UnidentifiedImageError, OSError):
            continue                                   # "does not decode" is reported by the browser
        if OVERLAPS_KEY not in text:
            problems.append(f"figure {name!r} has no text-overlap record (not saved by figures.to_png)")
            continue
        for first, second in json.loads(text[OVERLAPS_KEY]):
            problems.append(f"figure {name!r}: text {first!r} overlaps {second!r}")
    return problems


class _PageReader(HTMLParser):
    """The text a reader sees (without scripts and styles) and the (src, alt, title) of images."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.text, self.images, self._skip = [], [], 0

    def handle_starttag(self, tag, attrs):
        self.text.append(" ")                      # tags separate words (the check allows spaces)
        if tag in ("script", "style"):
            self._skip += 1
        elif tag == "img":
            a = dict(attrs)
            self.images.append((a.get("src") or "", a.get("alt") or "", a.get("title") or ""))

    def handle_endtag(self, tag):
        self.text.append(" ")
        if tag in ("script", "style") and self._skip:
            self._skip -= 1

    def handle_data(self, data):
        if not self._skip:
            self.text.append(data)


def check_page_content(html: str | Path) -> list[str]:
    """The checks that need no browser: empty intervals in the text, overlapping figure texts."""
    path = Path(html)
    try:
        source = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        return [f"{path}: cannot read the page ({exc})"]
    reader = _PageReader()
    reader.feed(source)
    return empty_interval_problems(" ".join("".join(reader.text).split())) + figure_overlap_problems(reader.images)


def browser_available() -> str | None:
    """Why the check cannot run here (None when it can)."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "the selenium package is not installed (pip install '.[test]')"
    for tool in ("chromium", "chromedriver"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed (apt-get install chromium chromium-driver)"
    return None


def check_report(html: str | Path, screenshot: str | Path | None = None,
                 sections=("paper-A", "paper-B", "paper-C", "paper-D")) -> dict:
    """Run the checks; returns {'problems': [...], 'images': n, 'requests': [...]}."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    url = Path(html).resolve().as_uri()
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    profile = tempfile.mkdtemp(prefix="wsnloc-chromium-")
    options.add_argument(f"--user-data-dir={profile}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    problems = []
    try:
        driver.get_log("performance")             # drop the browser's own start-up page
        driver.get_log("browser")
        driver.get(url)
        images = driver.execute_script(
            "return Array.from(document.images).map(i => [i.complete, i.naturalWidth, i.alt, i.src, i.title]);")
        for complete, width, alt, _, _ in images:
            if not complete or width == 0:
                problems.append(f"image does not decode: {alt!r}")
        problems += figure_overlap_problems([(src, alt, title) for _, _, alt, src, title in images])
        problems += empty_interval_problems(driver.execute_script("return document.body.innerText;"))
        for section in sections:
            count = driver.execute_script(
                f"const s = document.getElementById('{section}'); return s ? s.querySelectorAll('table.paper').length : -1;")
            if count < 1:
                problems.append(f"section {section} is missing or has no paper table")
        for entry in driver.get_log("browser"):
            if entry["level"] == "SEVERE":
                problems.append(f"console error: {entry['message']}")
        requests = []
        for entry in driver.get_log("performance"):
            message = json.loads(entry["message"])["message"]
            if message["method"] == "Network.requestWillBeSent":
                requests.append(message["params"]["request"]["url"])
        for request in requests:
            if request != url and not request.startswith(("data:", "chrome://", "about:")):
                problems.append(f"network request beyond the report: {request}")
        if screenshot:
            driver.save_screenshot(str(screenshot))
        return {"problems": problems, "images": len(images), "requests": requests}
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("html")
    parser.add_argument("--screenshot")
    args = parser.parse_args(argv)
    reason = browser_available()
    if reason:
        problems = check_page_content(args.html)
        for problem in problems:
            print(problem, file=sys.stderr)
        print(f"{args.html}: {len(problems)} problem(s) in text and figures; browser check not possible: {reason}",
              file=sys.stderr)
        return 1 if problems else 2
    outcome = check_report(args.html, args.screenshot)
    for problem in outcome["problems"]:
        print(problem, file=sys.stderr)
    print(f"{args.html}: {outcome['images']} images, {len(outcome['requests'])} request(s), "
          f"{len(outcome['problems'])} problem(s)" + (f"; screenshot {args.screenshot}" if args.screenshot else ""))
    return 1 if outcome["problems"] else 0


if __name__ == "__main__":
    sys.exit(main())
