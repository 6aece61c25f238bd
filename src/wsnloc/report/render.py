"""Render the HTML report pages (jinja2, autoescaped); each figure goes through `figure`: a PNG data
URI by default, a PNG file beside the pages in the workflow (report.smk)."""

from __future__ import annotations

import base64
import datetime as dt
import math
import subprocess
from importlib import metadata
from pathlib import Path

import jinja2
import numpy as np
import pandas as pd
import yaml

from wsnloc import experiments
from wsnloc.config import config_hash
from wsnloc.validation import dataset_kind

PACKAGES = ("wsnloc", "snakemake", "numpy", "scipy", "pandas", "pyarrow", "filterpy", "matplotlib", "jinja2")


def png_data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


DIVERGED = 1e6      # |value| above this in a metric that `diverged` applies to (metres, ANEES): "diverged"
LARGEST_PLAIN = 1e12   # |value| from this on is written in powers of ten (at most 12 digits in a number)


def counted(n, noun: str) -> str:
    """'1 run', '2 runs': a count with its noun in the singular or plural (English -s)."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def fmt_number(value, digits: int = 3, unit: str = "", signed: bool = False, diverged: bool = False) -> str:
    """The one number formatter of the report: `digits` significant digits, but never fewer than
    the integer part (1234.5 -> 1235 at 3 digits; digits 0: whole numbers), then the unit.
    Empty for a missing value; "not finite" for inf / nan of a float; "diverged" above DIVERGED
    where `diverged` (position errors in m, consistency statistics); powers of ten from
    LARGEST_PLAIN on and below 1e-4 (1.2e41, 3.1e-5); Python and numpy integers as they are
    (counts). signed: a leading + for positive values."""
    if value is None or (not isinstance(value, (int, float, np.number)) and pd.isna(value)):
        return ""
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value)).lower()
    if isinstance(value, (int, np.integer)) and abs(value) < LARGEST_PLAIN:
        return f"{'+' if signed and value > 0 else ''}{int(value):d}{chr(0x2009) + unit if unit else ''}"
    v = float(value)
    if math.isnan(v):
        return ""
    if math.isinf(v):
        return "not finite"
    if diverged and abs(v) > DIVERGED:
        return "diverged"
    sign = "+" if signed and v > 0 else ""
    if v != 0 and (abs(v) >= LARGEST_PLAIN or (abs(v) < 1e-4 and digits > 0)):
        mantissa, exponent = f"{v:.{max(digits, 1) - 1}e}".split("e")
        text = f"{mantissa}e{int(exponent)}"
    else:
        decimals = 0 if digits <= 0 or v == 0 else max(0, digits - 1 - math.floor(math.log10(abs(v))))
        text = f"{v:.{decimals}f}".removeprefix("-") if round(v, decimals) == 0 else f"{v:.{decimals}f}"
    return f"{sign}{text}{chr(0x2009) + unit if unit else ''}"


class FigureFiles:
    """Figures written once as PNG files under reports/pages/figures (shared by every page that
    shows them; a page is light and the report can be opened offline from the folder): calling
    it with PNG bytes returns the file's path relative to reports/. Equal bytes are one file."""

    def __init__(self, reports_dir: str | Path):
        self.reports_dir = Path(reports_dir)
        self.folder = self.reports_dir / PAGES_DIR / "figures"
        self.folder.mkdir(parents=True, exist_ok=True)
        self.written: dict[bytes, str] = {}

    def __call__(self, png: bytes, name: str = "figure") -> str:
        if png not in self.written:
            import hashlib

            file = self.folder / f"{name}-{hashlib.sha256(png).hexdigest()[:12]}.png"
            file.write_bytes(png)
            self.written[png] = file.relative_to(self.reports_dir).as_posix()
        return self.written[png]


def git_commit(cwd: str | Path = ".") -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, timeout=10)
        commit = out.stdout.strip() or "unknown (not a git checkout)"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return commit + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown (git not available)"


def package_versions() -> dict[str, str]:
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


KIND_LABEL = {"simulated": "SIMULATED", "synthetic": "SYNTHETIC (not measured)", "measured": "MEASURED"}


def data_banner(config: dict) -> list[str]:
    """One sentence per dataset saying what its data are (config datasets.<name>.kind: simulated,
    synthetic or measured; default from its source) and where they came from."""
    lines = []
    for name, spec in config["datasets"].items():
        kind = dataset_kind(spec)
        if kind == "simulated":
            own = spec.get("scenario_runs") or {}
            fewer = f" ({', '.join(f'{s}: {n}' for s, n in own.items())})" if own else ""
            lines.append(f"{name}: SIMULATED campaign (wsnloc simulator, {config['runs']} runs per scenario{fewer}, "
                         f"base seed {config['seed']}) — not the papers' measurements.")
        else:
            lines.append(f"{name}: {KIND_LABEL[kind]} logs from {spec['raw_dir']}.")
    return lines


def results_table(results: pd.DataFrame, experiment: str, table: str, scenario: str) -> list[dict]:
    """The rows of one table and scenario that have a value (a statistic the data cannot give,
    such as NLOS errors without NLOS links or RSS fits without RSS, is left out)."""
    sel = results[(results["experiment"] == experiment) & (results["table"] == table) & (results["scenario"] == scenario)
                  & results["value"].notna()]
    return sel.to_dict(orient="records")


PAGES_DIR = "pages"      # the pages beside the summary (reports/index.html), and their figures in pages/figures


def _environment(template_dir: str | Path) -> jinja2.Environment:
    env = jinja2.Environment(
        # the shared templates, then each paper's own partial (wsnloc/experiments/paper_x/section.html.j2)
        loader=jinja2.FileSystemLoader([str(template_dir), str(Path(experiments.__file__).parent)]),
        autoescape=jinja2.select_autoescape(default=True, default_for_string=True),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["num"] = fmt_number
    env.filters["counted"] = counted
    return env


def page_list(context: dict) -> list[dict]:
    """The report's pages in reading order: the summary (index.html), each study, each paper,
    each dataset's data quality, provenance; each {id, file (relative to reports/), label,
    template, group, item (the section's context)}. Files are also set on the studies,
    papers and datasets of `context` (the summary links to them)."""
    pages = [{"id": "index", "file": "index.html", "label": "Summary", "template": "summary.html.j2",
              "group": "Report", "item": None}]
    for kind, group, template, items, key, label in (
            ("study", "Studies", "study.html.j2", context["studies"], "id", "{}"),
            ("paper", "Papers", "paper.html.j2", context["papers"], "id", "Paper {}"),
            ("data", "Data quality", "data.html.j2", context["datasets"], "name", "{}")):
        for item in items:
            item["file"] = f"{PAGES_DIR}/{kind}-{item[key]}.html"
            pages.append({"id": f"{kind}-{item[key]}", "file": item["file"], "label": label.format(item[key]),
                          "template": template, "group": group, "item": item, "kind": kind})
    files = {page["id"]: page["file"] for page in pages}
    for line in context.get("summary", []):          # the summary's table of papers (sections.summary)
        line["file"] = files[f"paper-{line['id']}"]
    pages.append({"id": "provenance", "file": f"{PAGES_DIR}/provenance.html", "label": "Provenance",
                  "template": "provenance.html.j2", "group": "Report", "item": None})
    for k, page in enumerate(pages):
        page["previous"] = pages[k - 1] if k > 0 else None
        page["next"] = pages[k + 1] if k + 1 < len(pages) else None
    return pages


def render_pages(template_dir: str | Path, context: dict) -> dict[str, str]:
    """Every page of the report (page_list) rendered: {file relative to reports/: html}. Each
    page gets the whole context plus `page` (title, its study / paper / dataset, neighbours),
    `root` (its way back to reports/) and the navigation `nav` (groups of links)."""
    env = _environment(template_dir)
    pages = page_list(context)
    nav = []
    for page in pages:
        if not nav or nav[-1]["name"] != page["group"]:
            nav.append({"name": page["group"], "links": []})
        nav[-1]["links"].append(page)
    any_simulated = any(ds["kind"] == "simulated" for ds in context["datasets"])
    out = {}
    for page in pages:
        item = page["item"]
        kind = page.get("kind")
        view = {"id": page["id"], "title": page["label"], "previous": page["previous"], "next": page["next"],
                "dataset": item if kind == "data" else None, "paper": item if kind == "paper" else None,
                "study": item if kind == "study" else None}
        root = "" if "/" not in page["file"] else "../"
        out[page["file"]] = env.get_template(page["template"]).render(
            **context, page=view, root=root, nav=nav, any_simulated=any_simulated)
    return out


def dataset_has(config_spec: dict, summaries: list[dict]) -> dict[str, bool]:
    """What a dataset has, for the sections the report shows: IMU samples, RSS samples (in
    any run of its scenarios' summaries) and walls (in its campaign file)."""
    runs = [run for summary in summaries for run in summary.get("per_run", [])]
    try:
        walls = bool(yaml.safe_load(Path(config_spec["campaign"]).read_text()).get("walls"))
    except (OSError, AttributeError, yaml.YAMLError):
        walls = False
    return {"imu": any(run.get("imu", 0) > 0 for run in runs), "rss": any(run.get("rss", 0) > 0 for run in runs),
            "walls": walls}


def build_context(config: dict, summaries: list[dict], results: pd.DataFrame, figures: dict[str, dict[str, bytes]],
                  floor_plans: dict[str, bytes], figure=png_data_uri) -> dict:
    """Everything the templates show; `figure` turns a figure's PNG bytes into an image
    source (a data URI by default; the report job writes files, FigureFiles)."""
    datasets = []
    for name, spec in config["datasets"].items():
        scenarios = []
        for summary in summaries:
            if summary["label"].split("/", 1)[0] != name:
                continue
            label = summary["label"]
            scenarios.append({
                "label": label,
                "summary": summary,
                "range_error": results_table(results, "data", "Range error", label),
                "path_loss": results_table(results, "data", "RSS path-loss fit", label),
            })
        has = dataset_has(spec, [sc["summary"] for sc in scenarios])
        for sc in scenarios:    # only the figures data.html.j2 shows are written (no orphan placeholder)
            shown = {"rss_distance": bool(sc["path_loss"]), "imu_resampling": has["imu"]}
            sc["figures"] = {k: figure(v) for k, v in figures.get(sc["label"], {}).items() if shown.get(k, True)}
        kind = dataset_kind(spec)
        datasets.append({"name": name, "spec": spec, "scenarios": scenarios, "kind": kind, "has": has,
                         "has_list": [{"imu": "IMU", "rss": "RSS", "walls": "walls"}[k] for k, v in has.items() if v],
                         "banner": next(line for line in data_banner({**config, "datasets": {name: spec}})),
                         "floor_plan": figure(floor_plans[name]) if name in floor_plans else None})
    checksums = [
        {"scenario": s["label"], "run": run, "file": file, **info}
        for s in summaries for run, files in s.get("inventory", {}).items() for file, info in files.items()
    ]
    return {
        "title": config["report"]["title"],
        "banner": data_banner(config),
        "datasets": datasets,
        "experiments": sorted(results["experiment"].dropna().unique()),
        "summary": [],                   # per paper, filled in once the paper sections are built (sections.summary)
        "papers": [], "studies": [],     # filled in by the report job (sections)
        "ranging": None,                 # the ranging validation section, when configured (sections.ranging_section)
        "provenance": {
            "config_hash": config_hash(config),
            "config_yaml": yaml.safe_dump(config, sort_keys=False),
            "git_commit": git_commit(),
            "packages": package_versions(),
            "built": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"),
            "checksums": checksums,
        },
    }
