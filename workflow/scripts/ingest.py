"""Snakemake adapter: ingest every run of one scenario into Parquet tables."""

from wsnloc.campaign import Campaign
from wsnloc.io.ingest import ingest_scenario
from wsnloc.workflow import script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "ingest")
campaign = Campaign.load(sm.input.campaign)
inventory = ingest_scenario(sm.params.format, dict(zip(sm.params.runs, sm.params.raw_dirs)), campaign,
                            sm.output.tables, sm.params.max_quarantine_share)
for run, files in inventory.items():
    log.info("%s: %s", run, {name: (f["data_lines"], f["quarantined"]) for name, f in files.items()})
