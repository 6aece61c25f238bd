# Studies (config `studies`): one job per cell (study, dataset/scenario, estimator) with all
# its runs and anchor subsets, then one summary job per study. Helpers in common.smk.


rule study_cell:
    input:
        unpack(study_cell_inputs),
    output:
        estimates="data/processed/studies/{study}/{dataset}/{scenario}/{cell}/estimates.parquet",
        metrics="data/processed/studies/{study}/{dataset}/{scenario}/{cell}/metrics.csv",
        quality="data/processed/studies/{study}/{dataset}/{scenario}/{cell}/quality.parquet",
    params:
        cell=study_cell_spec,
        label="{dataset}/{scenario}",
    priority: PRIORITY["cell"]
    log:
        "logs/studies/{study}/{dataset}-{scenario}-{cell}.log",
    conda:
        ENV
    script:
        "../scripts/study_cell.py"


rule study_summary:
    input:
        metrics=lambda w: [f"data/processed/studies/{w.study}/{d}/{s}/{c}/metrics.csv" for d, s, c in STUDY_CELLS[w.study]],
        estimates=lambda w: [f"data/processed/studies/{w.study}/{d}/{s}/{c}/estimates.parquet"
                             for d, s, c in STUDY_CELLS[w.study]],
        quality=lambda w: [f"data/processed/studies/{w.study}/{d}/{s}/{c}/quality.parquet"
                           for d, s, c in STUDY_CELLS[w.study]],
        references=study_reference_inputs,
    output:
        results="data/processed/studies/{study}/results.csv",
        cdf="data/processed/studies/{study}/figures/error_cdf.png",
        errors="data/processed/studies/{study}/figures/error_over_time.png",
        tracks="data/processed/studies/{study}/figures/trajectories.png",
        bounds="data/processed/studies/{study}/figures/pcrb_vs_rmse.png",
        consistency="data/processed/studies/{study}/figures/consistency.png",
        bars="data/processed/studies/{study}/figures/estimators.png",
    params:
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
