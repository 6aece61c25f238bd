"""Load the built report in headless Chromium and check what a reader would see.

The report is a summary page (reports/index.html) and the pages it links to. Checks, on the
summary and every report page reachable from it by links: no console errors; no network
request other than the report's own files (and inline data: images); every image decodes;
every link to a page of the report reaches an existing page and, with a #fragment, an
element of that id; every page of the report folder is linked from the summary; every paper
section holds its tables; no box of class `fit` (a table meant to fit the page) scrolls sideways
at the check's width. Saves screenshots (at a set width). Needs Debian's `chromium` and
`chromium-driver` and the `selenium` package;
`python -m wsnloc.report.browser_check reports/index.html --screenshots DIR`.

Three checks need no browser and also run without one, on every page: no empty interval
"[, ]" in the text, no number of more than MAX_DIGITS digits, and no figure whose texts
overlap (each PNG carries the overlapping pairs found when it was saved, in the text chunk
wsnloc.report.figures.OVERLAPS_KEY).
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
from urllib.parse import unquote, urldefrag, urlparse

from PIL import Image, UnidentifiedImageError

from wsnloc.report.figures import OVERLAPS_KEY

CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage"]
WIDTH_PX = 1400          # window width of the check and its screenshots
MAX_DIGITS = 12          # a number with more digits than this is unreadable (a formatter was bypassed)
LONG_NUMBER = re.compile(rf"(?<![\w.])\d{{{MAX_DIGITS + 1},}}(?!\w)")   # not inside a hash or name


EMPTY_INTERVAL = re.compile(r"\[\s*,\s*\]")
PNG_DATA_URI = "data:image/png;base64,"


def empty_interval_problems(page_text: str) -> list[str]:
    """One problem per empty interval "[, ]" in the page text, quoting its surroundings."""
    problems = []
    for match in EMPTY_INTERVAL.finditer(page_text):
        context = " ".join(page_text[max(0, match.start() - 60):match.end() + 20].split())
        problems.append(f"empty interval '[, ]' in the page text: ...{context}...")
    return problems


def long_number_problems(page_text: str) -> list[str]:
    """One problem per number of more than MAX_DIGITS digits in the page text."""
    return [f"number of {len(m.group())} digits in the page text: ...{page_text[max(0, m.start() - 40):m.end()]}..."
            for m in LONG_NUMBER.finditer(page_text)]


def _png_bytes(src: str, base: Path | None) -> bytes | None:
    """The bytes of an image: an inline PNG data URI, a file:// URL, or a path relative to
    `base` (the page's folder) ending in .png; None for anything else (left to the other checks)."""
    if src.startswith(PNG_DATA_URI):
        return base64.b64decode(src[len(PNG_DATA_URI):], validate=True)
    url = urlparse(src)
    if url.scheme == "file":
        path = Path(unquote(url.path))
    elif not url.scheme and base is not None:
        path = base / unquote(url.path)
    else:
        return None
    return path.read_bytes() if path.suffix == ".png" and path.is_file() else None


def figure_overlap_problems(images, base: Path | None = None) -> list[str]:
    """Problems of the PNG figures of a page, given as (src, alt, title) triples (src a data
    URI, a file:// URL or a path relative to `base`).

    A figure fails when its OVERLAPS_KEY chunk lists overlapping texts, or when it has no such
    chunk (it was not saved by wsnloc.report.figures.to_png, so nothing checked it).
    Images that are neither are left to the other checks.
    """
    problems = []
    for number, (src, alt, title) in enumerate(images, start=1):
        name = alt or title or f"image {number}"
        try:
            png = _png_bytes(src, base)
            if png is None:
                continue
            text = Image.open(io.BytesIO(png)).text
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
    """The checks that need no browser, on one page: empty intervals and numbers of more than
    MAX_DIGITS digits in the text, overlapping figure texts."""
    path = Path(html)
    try:
        source = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        return [f"{path}: cannot read the page ({exc})"]
    reader = _PageReader()
    reader.feed(source)
    text = " ".join("".join(reader.text).split())
    return empty_interval_problems(text) + long_number_problems(text) + figure_overlap_problems(reader.images, path.parent)


def report_pages(html: str | Path) -> list[Path]:
    """The summary page and every .html file in its folder and below (the report's pages)."""
    summary = Path(html).resolve()
    return [summary] + sorted(p.resolve() for p in summary.parent.rglob("*.html") if p.resolve() != summary)


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


def _local_target(href: str, root: Path) -> tuple[Path, str] | None:
    """(file, fragment) of a link to a file of the report (under `root`), else None."""
    url, fragment = urldefrag(href)
    parsed = urlparse(url)
    if parsed.scheme != "file":
        return None
    path = Path(unquote(parsed.path))
    return (path, fragment) if path.is_relative_to(root) else None


def check_report(html: str | Path, screenshot: str | Path | None = None,
                 sections=("paper-A", "paper-B", "paper-C", "paper-D"), screenshots: str | Path | None = None,
                 width: int = WIDTH_PX) -> dict:
    """Run the checks on the summary page `html` and every report page it links to (directly
    or through other pages); returns {'problems': [...], 'images': n, 'requests': [...], 'pages': [...]}.
    screenshot: a screenshot of the summary; screenshots: a folder with one per page (full
    page height, `width` px wide). sections: ids that must be on some page, each with a paper table."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    summary = Path(html).resolve()
    root = summary.parent
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for flag in CHROMIUM_FLAGS + [f"--window-size={width},1200"]:
        options.add_argument(flag)
    profile = tempfile.mkdtemp(prefix="wsnloc-chromium-")
    options.add_argument(f"--user-data-dir={profile}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    problems, requests, image_count = [], [], 0
    ids, links, paper_tables = {}, [], {}
    try:
        driver.get_log("performance")             # drop the browser's own start-up page
        driver.get_log("browser")
        queue, seen = [summary], set()
        while queue:
            page = queue.pop(0)
            if page in seen:
                continue
            seen.add(page)
            name = page.relative_to(root).as_posix()
            driver.get(page.as_uri())
            images = driver.execute_script(
                "return Array.from(document.images).map(i => [i.complete, i.naturalWidth, i.alt, i.src, i.title]);")
            image_count += len(images)
            for complete, image_width, alt, _, _ in images:
                if not complete or image_width == 0:
                    problems.append(f"{name}: image does not decode: {alt!r}")
            problems += [f"{name}: {p}" for p in figure_overlap_problems([(src, alt, title) for _, _, alt, src, title in images])]
            for heading in driver.execute_script(
                    "return Array.from(document.querySelectorAll('.fit')).filter(e => e.scrollWidth > e.clientWidth + 1)"
                    ".map(e => { let h = e.previousElementSibling; while (h && !/^H[1-6]$/.test(h.tagName)) "
                    "h = h.previousElementSibling; return h ? h.textContent : e.textContent.slice(0, 60); });"):
                problems.append(f"{name}: a table that must fit the page width scrolls sideways: {heading!r}")
            text = driver.execute_script("return document.body.innerText;")
            problems += [f"{name}: {p}" for p in empty_interval_problems(text) + long_number_problems(text)]
            ids[page] = set(driver.execute_script("return Array.from(document.querySelectorAll('[id]')).map(e => e.id);"))
            paper_tables.update(driver.execute_script(
                "const out = {}; for (const s of document.querySelectorAll('section[id]')) "
                "out[s.id] = s.querySelectorAll('table.paper').length; return out;"))
            for href in driver.execute_script("return Array.from(document.links).map(a => a.href);"):
                target = _local_target(href, root)
                if target is not None:
                    links.append((page, href, *target))
                    if target[0].suffix == ".html" and target[0].is_file():
                        queue.append(target[0])
            for entry in driver.get_log("browser"):
                if entry["level"] == "SEVERE":
                    problems.append(f"{name}: console error: {entry['message']}")
            for entry in driver.get_log("performance"):
                message = json.loads(entry["message"])["message"]
                if message["method"] == "Network.requestWillBeSent":
                    requests.append(message["params"]["request"]["url"])
            if screenshots:
                Path(screenshots).mkdir(parents=True, exist_ok=True)
                height = driver.execute_script("return document.documentElement.scrollHeight;")
                driver.set_window_size(width, min(int(height) + 120, 16000))
                driver.save_screenshot(str(Path(screenshots) / (name.replace("/", "_").removesuffix(".html") + ".png")))
                driver.set_window_size(width, 1200)
            if screenshot and page == summary:
                driver.save_screenshot(str(screenshot))
        for page, href, target, fragment in links:
            where = page.relative_to(root).as_posix()
            if not target.is_file():
                problems.append(f"{where}: link {href} reaches no file")
            elif fragment and target in ids and fragment not in ids[target]:
                problems.append(f"{where}: link {href}: no element with id {fragment!r} on that page")
        from_summary = {target for page, _, target, _ in links if page == summary}
        for page in report_pages(summary)[1:]:
            if page not in from_summary:
                problems.append(f"page {page.relative_to(root).as_posix()} is not linked from the summary")
        for section in sections:
            if paper_tables.get(section, 0) < 1:
                problems.append(f"section {section} is missing or has no paper table")
        for request in requests:
            target = _local_target(request, root)
            # chrome:// and chrome-untrusted:// are the browser's own pages (its new-tab page), not the report's
            if target is None and not request.startswith(("data:", "chrome://", "chrome-untrusted://", "about:")):
                problems.append(f"network request beyond the report: {request}")
        return {"problems": problems, "images": image_count, "requests": requests,
                "pages": sorted(p.relative_to(root).as_posix() for p in seen)}
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("html", help="the report's summary page (reports/index.html)")
    parser.add_argument("--screenshot", help="a screenshot of the summary page")
    parser.add_argument("--screenshots", help="a folder for one full-height screenshot per page")
    parser.add_argument("--width", type=int, default=WIDTH_PX, help="window width in px")
    args = parser.parse_args(argv)
    reason = browser_available()
    if reason:
        problems = [f"{page.name}: {p}" for page in report_pages(args.html) for p in check_page_content(page)]
        for problem in problems:
            print(problem, file=sys.stderr)
        print(f"{args.html}: {len(problems)} problem(s) in text and figures; browser check not possible: {reason}",
              file=sys.stderr)
        return 1 if problems else 2
    outcome = check_report(args.html, args.screenshot, screenshots=args.screenshots, width=args.width)
    for problem in outcome["problems"]:
        print(problem, file=sys.stderr)
    print(f"{args.html}: {len(outcome['pages'])} pages, {outcome['images']} images, {len(outcome['requests'])} "
          f"request(s), {len(outcome['problems'])} problem(s)"
          + (f"; screenshots in {args.screenshots}" if args.screenshots else ""))
    return 1 if outcome["problems"] else 0


if __name__ == "__main__":
    sys.exit(main())
