"""Snakemake adapter: a study's results rows and figures over all its cells."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.errors import WsnlocError
from wsnloc.io import tables
from wsnloc.report import bound_figures, figures
from wsnloc.experiments.realdata import scenario_reference_rows
from wsnloc.studies import bound_summary, diagnosis_rows, estimator_panels, results_rows, study_panels

study = sm.wildcards.study
scenarios = {label: (pd.read_csv(metrics, keep_default_na=False, na_values=[""]), tables.read(estimates),
                     pd.read_parquet(quality))
             for label, metrics, estimates, quality in zip(sm.params.labels, sm.input.metrics, sm.input.estimates,
                                                           sm.input.quality)}
for label, path in zip(sm.params.labels, sm.input.metrics):
    if "findings" not in scenarios[label][0]:   # written by a build before the diagnosis sentences were kept
        raise WsnlocError(f"study {study}: {path} has no `findings` column; re-run its scenario job "
                          f"(snakemake --cores 2 -R study_scenario)")
rows, estimates, bayesian, diagnosed = [], {}, [], []
for cell in sm.params.cells:          # in the config's order: scenario, then cell
    metrics, estimated, quality = (frame[frame["cell"] == cell["cell"]].drop(columns="cell")
                                   for frame in scenarios[cell["label"]])
    if metrics.empty or estimated.empty:   # a cell never vanishes from results.csv unnoticed
        raise WsnlocError(f"study {study}: cell {cell['cell']} has no rows in the outputs of {cell['label']} "
                          f"(data/processed/studies/{study}/{cell['label']}/); re-run its scenario job")
    rows += results_rows(study, cell["cell"], cell["label"], metrics)
    diagnosed += diagnosis_rows(cell["label"], cell["cell"], metrics)
    estimates[(cell["label"], cell["cell"])] = estimated
    if len(quality):
        bayesian.append((cell, quality))
bound_rows, bound_panels, consistency_panels = bound_summary(study, *map(list, zip(*bayesian))) if bayesian \
    else ([], [], [])
rows += bound_rows
rows += scenario_reference_rows(study, sm.params.references)
results.write(rows, sm.output.results)
pd.DataFrame(diagnosed, columns=["scenario", "cell", "run", "subset", "findings"]).to_csv(sm.output.diagnosis,
                                                                                          index=False)
pcrb_png, anees_png = bound_figures.bound_and_anees_figures(bound_panels, consistency_panels,
                                                            none="no Bayesian filter cell in this study")
Path(sm.output.bounds).write_bytes(pcrb_png)
Path(sm.output.consistency).write_bytes(anees_png)
cdf, errors, tracks, heights = study_panels(estimates)
Path(sm.output.cdf).write_bytes(figures.error_cdf(cdf, xmax=None))
Path(sm.output.errors).write_bytes(figures.error_over_time(errors))
Path(sm.output.tracks).write_bytes(figures.trajectories(tracks))
# empty where no cell estimates a height: the report shows (and writes) no figure for it
Path(sm.output.heights).write_bytes(figures.height_over_time(heights) if heights else b"")
Path(sm.output.bars).write_bytes(figures.estimator_bars(estimator_panels(rows, sm.params.bar_stats)))
log.info("study %s: %d cells, %d results rows", study, len(estimates), len(rows))
