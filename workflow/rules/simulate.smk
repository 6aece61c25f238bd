# The campaign simulator writes raw logs, exactly as a testbed logger would.
# Only datasets with `source: simulate` have this rule, so real logs are never overwritten.


rule simulate:
    input:
        campaign=campaign_file,
    output:
        expand(
            "data/raw/{{dataset}}/{{scenario}}/{run}/{file}",
            run=simulated_runs(config),
            file=SIM_FILES,
        ),
    params:
        runs=config["runs"],
        seed=config["seed"],
        root="data/raw/{dataset}/{scenario}",
    wildcard_constraints:
        dataset="|".join(SIMULATED) or "^$",
    log:
        "logs/simulate/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/simulate.py"
