"""Snakemake adapter: convert one public dataset into the generic format (wsnloc.io.convert)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from wsnloc.io.convert import CONVERTERS, QUARANTINE_FILE
for run in CONVERTERS[sm.params.dataset](sm.params.source, sm.params.raw_dir):
    bad = f"; {len(run.quarantine)} source line(s) quarantined in {run.run_dir / QUARANTINE_FILE}" \
        if run.quarantine else ""
    log.info("wrote %s%s", run.run_dir, bad)
