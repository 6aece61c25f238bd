"""Render the self-contained HTML report (jinja2, autoescaped, images inlined as base64)."""

from __future__ import annotations

import base64
import datetime as dt
import subprocess
from importlib import metadata
from pathlib import Path

import jinja2
import pandas as pd
import yaml

from wsnloc.config import config_hash

PACKAGES = ("wsnloc", "snakemake", "numpy", "scipy", "pandas", "pyarrow", "filterpy", "matplotlib", "jinja2")


def png_data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def fmt_number(value, digits: int = 3) -> str:
    """Fixed decimals for display; empty for missing values."""
    if value is None or pd.isna(value):
        return ""
    if isinstance(value, (int,)) or (isinstance(value, float) and value.is_integer() and abs(value) >= 1000):
        return f"{int(value):d}"
    return f"{value:.{digits}f}"


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


def data_banner(config: dict) -> list[str]:
    """One sentence per dataset saying where its data came from."""
    lines = []
    for name, spec in config["datasets"].items():
        if spec["source"] == "simulate":
            lines.append(f"{name}: SIMULATED campaign (wsnloc simulator, {config['runs']} runs per scenario, "
                         f"base seed {config['seed']}) — not the papers' measurements.")
        else:
            lines.append(f"{name}: real logs from {spec['raw_dir']}.")
    return lines


def results_table(results: pd.DataFrame, experiment: str, table: str, scenario: str) -> list[dict]:
    """The rows of one table and scenario that have a value (a statistic the data cannot give,
    such as NLOS errors without NLOS links or RSS fits without RSS, is left out)."""
    sel = results[(results["experiment"] == experiment) & (results["table"] == table) & (results["scenario"] == scenario)
                  & results["value"].notna()]
    return sel.to_dict(orient="records")


def render(template_path: str | Path, context: dict) -> str:
    template_path = Path(template_path)
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(template_path.parent),
        autoescape=jinja2.select_autoescape(default=True, default_for_string=True),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["num"] = fmt_number
    return env.get_template(template_path.name).render(**context)


def build_context(config: dict, summaries: list[dict], results: pd.DataFrame, figures: dict[str, dict[str, bytes]],
                  floor_plans: dict[str, bytes]) -> dict:
    """Everything the template shows; figures are turned into data URIs here."""
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
                "figures": {k: png_data_uri(v) for k, v in figures.get(label, {}).items()},
            })
        datasets.append({"name": name, "spec": spec, "scenarios": scenarios,
                         "floor_plan": png_data_uri(floor_plans[name]) if name in floor_plans else None})
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
        "provenance": {
            "config_hash": config_hash(config),
            "config_yaml": yaml.safe_dump(config, sort_keys=False),
            "git_commit": git_commit(),
            "packages": package_versions(),
            "built": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"),
            "checksums": checksums,
        },
    }
