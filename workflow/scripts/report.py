"""Snakemake adapter: collect results rows and summaries, render the report's pages:
reports/index.html (the summary) and reports/pages/*.html with their figures."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

import importlib
import json
import shutil
from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis.nlos_severity import CLAIMS_TABLE as RANGING_SENSITIVITY
from wsnloc.config import read_yaml
from wsnloc.experiments.sensitivity import TABLE as SENSITIVITY
from wsnloc.report import explanations
from wsnloc.report.render import PAGES_DIR, FigureFiles, build_context, render_pages
from wsnloc.report.sections import ranging_section, sensitivity_table, static_bounds_section, study_section, summary

config = sm.params.config

summaries = [json.loads(Path(p).read_text()) for p in sm.input.summaries]
result_files = list(sm.input.results) + [p for p in list(sm.input.studies) + list(sm.input.paper_files)
                                         if p.endswith("results.csv")] \
    + [p for p in sm.input.bounds if p.endswith(".csv")] \
    + [p for p in sm.input.ranging if p.endswith(".csv")]   # static bounds, subset Monte Carlo, ranging validation rows
all_results = pd.concat([results.read(p) for p in result_files], ignore_index=True)
results.write(all_results, sm.output.results)

reports = Path(sm.output.html).parent
shutil.rmtree(reports / PAGES_DIR, ignore_errors=True)    # no page or figure of an earlier build is left
figure = FigureFiles(reports)

scenario_figures = {}
for path in map(Path, sm.input.figures):
    label = f"{path.parents[2].name}/{path.parents[1].name}"
    scenario_figures.setdefault(label, {})[path.stem] = path.read_bytes()

floor_plans = {Path(p).parents[1].name: Path(p).read_bytes() for p in sm.input.floor_plans}   # rule geometry

final_results = results.read(sm.output.results)
context = build_context(config, summaries, final_results, scenario_figures, floor_plans, figure)
for ds in context["datasets"]:   # static bounds of the dataset (rule geometry), when configured
    maps = [Path(p) for p in sm.input.bounds if p.endswith(".png") and Path(p).parts[2] == ds["name"]]
    ds["bounds"] = static_bounds_section(final_results, ds["name"], figure(maps[0].read_bytes())) if maps else None
if sm.input.ranging:    # the ranging validation (rule ranging_validation): table, figure, what was skipped
    ranging = {Path(p).name: Path(p) for p in sm.input.ranging}
    note = json.loads(ranging["note.json"].read_text())
    context["ranging"] = ranging_section(final_results, note["scenarios"],
                                         figure(ranging["ranging_validation.png"].read_bytes()), note["notes"])
papers = read_yaml(sm.input.papers)
numbers = explanations.Numbers(final_results, {summary["label"]: summary for summary in summaries}, config)
for study, spec in sm.params.studies.items():
    pngs = [Path(p) for p in sm.input.studies if p.endswith(".png") and Path(p).parts[3] == study
            and Path(p).stat().st_size]          # an empty PNG: the figure does not apply (no 3-D cell)
    diagnosed = next(pd.read_csv(p, keep_default_na=False) for p in sm.input.studies
                     if p.endswith("diagnosis.csv") and Path(p).parts[3] == study)
    context["studies"].append(study_section(final_results, study, spec, {path.stem: figure(path.read_bytes())
                                                                         for path in pngs},
                                            config["report"]["cell_stats"], diagnosed))
    context["studies"][-1]["bound_whys"] = explanations.study_bound_whys(numbers, context["studies"][-1])
for paper, labels in sm.params.papers.items():   # each paper's section: wsnloc.experiments.<paper>.report
    spec = config["experiments"][paper]
    outputs = {Path(p).name: Path(p) for p in sm.input.paper_files if Path(p).parts[2] == paper}
    claims = json.loads(outputs["claims.json"].read_text())
    figures_uri = {path.stem: figure(path.read_bytes()) for path in outputs.values() if path.suffix == ".png"}
    module = importlib.import_module(f"wsnloc.experiments.{paper}")
    section = importlib.import_module(f"wsnloc.experiments.{paper}.report").section(
        final_results, claims, figures_uri, papers[module.EXPERIMENT], list(labels), spec, numbers, config)
    section["sensitivity"] = sensitivity_table(final_results, module.EXPERIMENT, section["claims"], SENSITIVITY)
    section["ranging_sensitivity"] = sensitivity_table(final_results, module.EXPERIMENT, section["claims"],
                                                       RANGING_SENSITIVITY)
    context["papers"].append(section)
context["summary"] = summary(context["papers"])
pages = render_pages(Path(sm.input.templates[0]).parent, context)
for file, html in pages.items():
    (reports / file).parent.mkdir(parents=True, exist_ok=True)
    (reports / file).write_text(html, encoding="utf-8")
size = sum(f.stat().st_size for f in reports.rglob("*") if f.is_file() and f.suffix in (".html", ".png"))
log.info("report: %d pages and %d figures, %d bytes; %d results rows", len(pages), len(figure.written), size,
         len(all_results))
