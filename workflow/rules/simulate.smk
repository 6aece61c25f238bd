# The campaign simulators write raw logs, exactly as a testbed logger would. One rule per
# format (their files differ) and per shard of the Monte Carlo runs (config `shards`).
# Only datasets with `source: simulate` match these rules, so real logs are never overwritten.

for _format in ("newcom", "cricket"):
    for _shard, _runs in simulated_shards(config).items():

        rule:
            name:
                f"simulate_{_format}_{_shard.replace('-', '')}"
            input:
                campaign=campaign_file,
            output:
                expand(
                    "data/raw/{{dataset}}/{{scenario}}/{run}/{file}",
                    run=_runs,
                    file=RAW_FILES[_format] + ["meta.yaml"],
                ),
            params:
                runs=_runs,
                total=config["runs"],
                seed=config["seed"],
                root="data/raw/{dataset}/{scenario}",
            priority: PRIORITY[f"simulate_{_format}"]
            wildcard_constraints:
                dataset=simulated_of(_format),
            log:
                f"logs/simulate/{{dataset}}-{{scenario}}-{_shard}.log",
            conda:
                ENV
            script:
                "../scripts/simulate.py"
