# The campaign simulators write raw logs, exactly as a testbed logger would; one rule per
# format because the files differ. Only datasets with `source: simulate` match these rules,
# so real logs are never overwritten.



rule simulate_newcom:
    input:
        campaign=campaign_file,
    output:
        expand(
            "data/raw/{{dataset}}/{{scenario}}/{run}/{file}",
            run=simulated_runs(config),
            file=RAW_FILES["newcom"] + ["meta.yaml"],
        ),
    params:
        runs=config["runs"],
        seed=config["seed"],
        root="data/raw/{dataset}/{scenario}",
    wildcard_constraints:
        dataset=simulated_of("newcom"),
    log:
        "logs/simulate/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/simulate.py"


rule simulate_cricket:
    input:
        campaign=campaign_file,
    output:
        expand(
            "data/raw/{{dataset}}/{{scenario}}/{run}/{file}",
            run=simulated_runs(config),
            file=RAW_FILES["cricket"] + ["meta.yaml"],
        ),
    params:
        runs=config["runs"],
        seed=config["seed"],
        root="data/raw/{dataset}/{scenario}",
    wildcard_constraints:
        dataset=simulated_of("cricket"),
    log:
        "logs/simulate/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/simulate.py"
