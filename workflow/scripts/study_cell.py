"""Snakemake adapter: one study cell (an estimator on every run and subset of one scenario)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from wsnloc.campaign import Campaign
from wsnloc.estimators import registry
from wsnloc.io import tables
from wsnloc.metrics.data_quality import load_runs
from wsnloc.studies import quality_table, run_cell

cell = sm.params.cell
name, params = cell["estimator"], cell["parameters"]
names = registry.get(name).tables(params)
campaign = Campaign.load(sm.input.campaign)
runs = load_runs(sm.input.tables, names, getattr(sm.input, "imu_5hz", None), first=cell["runs"])
donors = load_runs(sm.input.donors, ("ranges", "rss", "truth", "anchors")) if sm.input.donors else {}
cell_name = sm.wildcards.cell
estimates, metrics = run_cell(sm.params.label, cell_name, name, params, cell["subsets"], runs, campaign, donors)
tables.write("estimates", estimates, sm.output.estimates)
metrics.to_csv(sm.output.metrics, index=False, float_format="%.6g")
quality_table(estimates).to_parquet(sm.output.quality, index=False, compression="zstd")
log.info("%s on %s: %d runs x %d subsets, parameters %s", cell_name, sm.params.label, len(runs),
         len(cell["subsets"]), params)
