"""Snakemake adapter: every cell of a study on one scenario (each an estimator on every run and
subset), in one job: the runs are read once and the cells share what they derive from them
(epochs, fixes, the self-fit's passes: RunData's cache, studies.run_cells)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from wsnloc.campaign import Campaign
from wsnloc.estimators import registry
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.studies import run_cells

cells = sm.params.cells
names = list(dict.fromkeys(name for c in cells for name in registry.get(c["estimator"]).tables(c["parameters"])))
campaign = Campaign.load(sm.input.campaign)
runs = load_runs(sm.input.tables, names, getattr(sm.input, "imu_5hz", None), first=sm.params.runs)
donors = load_runs(sm.input.donors, ("ranges", "rss", "truth", "anchors")) if sm.input.donors else {}
estimates, metrics, quality = run_cells(sm.params.label, cells, sm.params.subsets, runs, campaign, donors)
tables.write("estimates_study", estimates, sm.output.estimates)
metrics.to_csv(sm.output.metrics, index=False, float_format="%.6g")
quality.to_parquet(sm.output.quality, index=False, compression="zstd")
log.info("%d cells on %s: %d runs x %d subsets", len(cells), sm.params.label, len(runs), len(sm.params.subsets))
