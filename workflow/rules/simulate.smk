# The campaign simulators write raw logs, exactly as a testbed logger would. One job per format
# (their files differ) and per shard of the Monte Carlo runs (config `shards`), over every
# simulated scenario of that format: each job pays its start-up once, not once per scenario.
# Only datasets with `source: simulate` are written here, so real logs are never overwritten.

for _format, _pairs in SIMULATED_PAIRS.items():
    for _shard in simulated_shards(config) if _pairs else []:
        # each scenario's runs of this shard (datasets.<d>.scenario_runs: fewer runs, maybe none here)
        _runs = {(d, s): shards_of(config, d, s).get(_shard, []) for d, s in _pairs}

        rule:
            name:
                f"simulate_{_format}_{_shard.replace('-', '')}"
            input:
                campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in _pairs}),
            output:
                # each run's folder (its raw logs and meta.yaml), one output per run
                [directory(raw_run_dir(config, d, s, run)) for d, s in _pairs for run in _runs[(d, s)]],
            params:
                scenarios=[{"dataset": d, "scenario": s, "campaign": config["datasets"][d]["campaign"],
                            "runs": _runs[(d, s)]} for d, s in _pairs if _runs[(d, s)]],
                seed=config["seed"],
            priority: PRIORITY[f"simulate_{_format}"]
            log:
                f"logs/simulate/{_format}-{_shard}.log",
            conda:
                ENV
            script:
                "../scripts/simulate.py"
