"""Snakemake adapter: the ranging validation (wsnloc.metrics.ranging_validation) - the real UWB
runs (when their source is there) and the 802.15.4a channel models alone beside the simulated
scenarios' rows of the data stage; results rows, the figure and a note of what was skipped."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

import json
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.metrics import ranging_validation as rv
from wsnloc.report.figures import ranging_validation as figure
from wsnloc.sim.seeding import run_seed_sequence

spec = sm.params.spec
rows, notes = [], []
real = spec.get("real") or {}
if real and Path(real["source"]).is_dir():
    errors = rv.real_errors(real["source"], real["campaign"])
    for link, group in errors.groupby("link"):
        rows += rv.rows(group, rv.EXPERIMENT, f"{real['dataset']}/{link.lower()}")
    notes.append(f"real UWB runs: {errors['run'].nunique()} cases of {real['dataset']} ({real['source']}), "
                 f"{len(errors)} ranges against RTK truth")
elif real:
    notes.append(f"real UWB runs skipped: their source {real['source']!r} is not there "
                 f"(ranging_validation.real.source)")
    log.info(notes[-1])
model_campaign = Campaign.load(sm.input.campaign)
rng = np.random.default_rng(run_seed_sequence(sm.params.seed, "ieee802154a", "ranging_validation", 1))
model = rv.channel_model_errors(model_campaign, spec["model_links_per_bin"], rng)
rows += rv.single_rows(model, rv.EXPERIMENT, "IEEE 802.15.4a model")
results.write(rows, sm.output.results)

simulated = pd.concat([results.read(p) for p in sm.input.results], ignore_index=True)
shown = pd.concat([simulated[simulated["table"] == rv.TABLE], results.read(sm.output.results)], ignore_index=True)
Path(sm.output.figure).parent.mkdir(parents=True, exist_ok=True)
Path(sm.output.figure).write_bytes(figure(rv.curves(shown)))
Path(sm.output.note).write_text(json.dumps({"notes": notes, "scenarios": list(spec["scenarios"])}, indent=1))
