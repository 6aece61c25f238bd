"""Snakemake adapter: convert one public dataset into the generic format (wsnloc.io.convert)."""

from wsnloc.io.convert import CONVERTERS, QUARANTINE_FILE
from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (injected by wsnloc.job_server: the rule's input, output, params, wildcards, log)
log = start_job(sm.log[0], "convert")
for run in CONVERTERS[sm.params.dataset](sm.params.source, sm.params.raw_dir):
    bad = f"; {len(run.quarantine)} source line(s) quarantined in {run.run_dir / QUARANTINE_FILE}" \
        if run.quarantine else ""
    log.info("wrote %s%s", run.run_dir, bad)
