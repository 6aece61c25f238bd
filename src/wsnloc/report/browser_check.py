"""Load the built report in headless Chromium and check what a reader would see.

Checks: no console errors; no network request other than the report file itself (and
its inline data: images); every image decodes; every paper section holds its tables.
Saves a screenshot. Needs Debian's `chromium` and `chromium-driver` and the `selenium`
package; `python -m wsnloc.report.browser_check reports/index.html --screenshot X.png`.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--window-size=1280,2000"]


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
            "return Array.from(document.images).map(i => [i.complete, i.naturalWidth, i.alt]);")
        for complete, width, alt in images:
            if not complete or width == 0:
                problems.append(f"image does not decode: {alt!r}")
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
        print(f"browser check not possible: {reason}", file=sys.stderr)
        return 2
    outcome = check_report(args.html, args.screenshot)
    for problem in outcome["problems"]:
        print(problem, file=sys.stderr)
    print(f"{args.html}: {outcome['images']} images, {len(outcome['requests'])} request(s), "
          f"{len(outcome['problems'])} problem(s)" + (f"; screenshot {args.screenshot}" if args.screenshot else ""))
    return 1 if outcome["problems"] else 0


if __name__ == "__main__":
    sys.exit(main())
