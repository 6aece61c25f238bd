# wsnloc workflow: raw logs -> Parquet -> (estimates -> metrics) -> report.
# Edit config/config.yaml, then run `snakemake --cores 2`.
import atexit
import sys

from snakemake.utils import min_version

from wsnloc.errors import WsnlocError
from wsnloc.validation import validate_config
from wsnloc.workflow import REPORT, RESULTS, compile_bytecode, finished_build, without_missing_sources

min_version("8.20")
compile_bytecode()   # each job imports wsnloc's modules: compiled once here, not in every job


configfile: "config/config.yaml"


# Datasets converted from a public source that is not there are skipped, with a message.
for _message in without_missing_sources(config):
    print(_message)
# Validated (and defaults filled in) before any job is planned: schema, campaigns, real-log
# folders, experiments' subsets, studies. Errors name the key: one message, no traceback.
try:
    validate_config(config, "config/schema.yaml")
except WsnlocError as error:
    sys.exit(f"error in the configuration: {error}")


include: "workflow/rules/common.smk"
include: "workflow/rules/convert.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/paper_d.smk"
include: "workflow/rules/paper_b.smk"
include: "workflow/rules/papers_ac.smk"
include: "workflow/rules/studies.smk"
include: "workflow/rules/bounds.smk"
include: "workflow/rules/ranging.smk"
include: "workflow/rules/report.smk"


rule all:
    input:
        REPORT,
        RESULTS,
    default_target: True


# Where the report is: printed at exit, after Snakemake's own closing lines.
onsuccess:
    atexit.register(print, finished_build())
