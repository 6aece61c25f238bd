# Studies (config `studies`): one job per (study, dataset/scenario) that runs every cell (estimator)
# of the study on all runs and anchor subsets of the scenario, then one summary job per study.
# Helpers in common.smk.


rule study_scenario:
    input:
        unpack(study_scenario_inputs),
    output:
        estimates="data/processed/studies/{study}/{dataset}/{scenario}/estimates.parquet",
        metrics="data/processed/studies/{study}/{dataset}/{scenario}/metrics.csv",
        quality="data/processed/studies/{study}/{dataset}/{scenario}/quality.parquet",
    params:
        cells=study_scenario_cells,
        subsets=lambda w: STUDIES[w.study].get("subsets") or ["all"],
        runs=lambda w: STUDIES[w.study].get("runs"),
        label="{dataset}/{scenario}",
    priority: PRIORITY["study"]
    log:
        "logs/studies/{study}/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/study_scenario.py"


rule study_summary:
    input:
        metrics=lambda w: [f"data/processed/studies/{w.study}/{label}/metrics.csv" for label in STUDIES[w.study]["scenarios"]],
        estimates=lambda w: [f"data/processed/studies/{w.study}/{label}/estimates.parquet"
                             for label in STUDIES[w.study]["scenarios"]],
        quality=lambda w: [f"data/processed/studies/{w.study}/{label}/quality.parquet"
                           for label in STUDIES[w.study]["scenarios"]],
        references=study_reference_inputs,
    output:
        results="data/processed/studies/{study}/results.csv",
        diagnosis="data/processed/studies/{study}/diagnosis.csv",     # each run's diagnosis sentences
        cdf="data/processed/studies/{study}/figures/error_cdf.png",
        errors="data/processed/studies/{study}/figures/error_over_time.png",
        tracks="data/processed/studies/{study}/figures/trajectories.png",
        heights="data/processed/studies/{study}/figures/height_over_time.png",
        bounds="data/processed/studies/{study}/figures/pcrb_vs_rmse.png",
        consistency="data/processed/studies/{study}/figures/consistency.png",
        bars="data/processed/studies/{study}/figures/estimators.png",
    params:
        labels=lambda w: STUDIES[w.study]["scenarios"],
        cells=lambda w: [{"label": f"{d}/{s}", "cell": c,
                          "parameters": cell_params(STUDIES[w.study], c, d, s, f"studies.{w.study}")}
                         for d, s, c in STUDY_CELLS[w.study]],
        bar_stats=config["report"]["cell_stats"],
        references=study_references,
    priority: PRIORITY["summary"]
    log:
        "logs/studies/{study}/summary.log",
    conda:
        ENV
    script:
        "../scripts/study_summary.py"
