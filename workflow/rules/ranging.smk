# Ranging validation (config `ranging_validation`): one job beside the summaries. The simulated
# scenarios' rows come from their data stage; the job adds the real UWB runs (converted from
# their public source in a scratch folder; skipped with a message when it is absent) and the
# IEEE 802.15.4a channel models alone, and draws the figure.
RANGING = config.get("ranging_validation") or {"scenarios": []}
RANGING_OUTPUTS = ["data/processed/ranging_validation/results.csv",
                   "data/processed/ranging_validation/figures/ranging_validation.png",
                   "data/processed/ranging_validation/note.json"] if RANGING["scenarios"] else []
_real = RANGING.get("real") or {}
if RANGING["scenarios"] and _real and not Path(_real["source"]).is_dir():
    print(f"ranging validation: real UWB runs skipped: their source {_real['source']!r} is not there "
          f"(ranging_validation.real.source)")

if RANGING["scenarios"]:

    rule ranging_validation:
        input:
            results=[f"data/processed/{label}/data_results.csv" for label in RANGING["scenarios"]],
            campaign=campaign_of_label(RANGING["scenarios"][0]),
            real=sorted(str(p) for p in Path(_real["source"]).rglob("*") if p.is_file())
            if _real and Path(_real["source"]).is_dir() else [],
        output:
            results=RANGING_OUTPUTS[0],
            figure=RANGING_OUTPUTS[1],
            note=RANGING_OUTPUTS[2],
        params:
            spec=RANGING,
            seed=config["seed"],
        priority: PRIORITY["geometry"]
        log:
            "logs/ranging_validation.log",
        conda:
            ENV
        script:
            "../scripts/ranging_validation.py"
