"""Snakemake adapter: collect results rows and summaries, render reports/index.html."""

import json
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.io import tables
from wsnloc.report import figures
from wsnloc.report.render import build_context, render
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "report")
config = sm.params.config

summaries = [json.loads(Path(p).read_text()) for p in sm.input.summaries]
all_results = pd.concat([results.read(p) for p in sm.input.results], ignore_index=True)
results.write(all_results, sm.output.results)

scenario_figures = {}
for path in map(Path, sm.input.figures):
    label = f"{path.parents[2].name}/{path.parents[1].name}"
    scenario_figures.setdefault(label, {})[path.stem] = path.read_bytes()

floor_plans = {}
for name, spec in config["datasets"].items():
    tables_dir = next(Path(p) for p in sm.input.tables if Path(p).parents[1].name == name)
    truth_files = sorted(tables_dir.glob("*/truth.parquet"))
    track = tables.read(truth_files[0]) if truth_files else None
    floor_plans[name] = figures.floor_plan(Campaign.load(spec["campaign"]), track)

context = build_context(config, summaries, results.read(sm.output.results), scenario_figures, floor_plans)
html = render(sm.input.template, context)
Path(sm.output.html).write_text(html, encoding="utf-8")
log.info("report: %d bytes, %d results rows", len(html), len(all_results))
