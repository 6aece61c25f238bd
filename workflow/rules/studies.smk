# Studies (config `studies`): one job per cell (study, dataset/scenario, estimator) with all
# its runs and anchor subsets, then one summary job per study.
from wsnloc.estimators import registry as _registry
from wsnloc.studies import cell_params, estimator_of, reads_rss

STUDIES = config.get("studies") or {}
STUDY_CELLS = {   # study: [(dataset, scenario, cell)]
    study: [(*label.split("/", 1), cell) for label in spec["scenarios"] for cell in spec["estimators"]]
    for study, spec in STUDIES.items()
}


def study_cell_spec(w):
    """Estimator name, resolved parameters and subsets of one cell (its Snakemake params)."""
    spec = STUDIES[w.study]
    params = cell_params(spec, w.cell, w.dataset, w.scenario, f"studies.{w.study}")
    return {"estimator": estimator_of(spec, w.cell), "parameters": params, "subsets": spec.get("subsets") or ["all"]}


def study_cell_inputs(w):
    """Tables of the scenario (+ 5 Hz IMU when read), and RSS donors of the same dataset
    when the scenario has a single run."""
    cell = study_cell_spec(w)
    estimator = _registry.get(cell["estimator"])
    inputs = {"tables": tables_of(w.dataset, w.scenario), "campaign": campaign_file(w), "donors": []}
    if "imu_5hz" in estimator.tables(cell["parameters"]):
        inputs["imu_5hz"] = imu_of(w.dataset, w.scenario)
    single = len(dataset_runs(config, w.dataset, w.scenario)) < 2
    if single and reads_rss(cell["estimator"], cell["parameters"]):
        inputs["donors"] = [p for s in config["datasets"][w.dataset]["scenarios"] if s != w.scenario
                            for p in tables_of(w.dataset, s)]
    return inputs


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
    priority: PRIORITY["estimator"]
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
    output:
        results="data/processed/studies/{study}/results.csv",
        cdf="data/processed/studies/{study}/figures/error_cdf.png",
        errors="data/processed/studies/{study}/figures/error_over_time.png",
        tracks="data/processed/studies/{study}/figures/trajectories.png",
        bounds="data/processed/studies/{study}/figures/pcrb_vs_rmse.png",
        consistency="data/processed/studies/{study}/figures/consistency.png",
    params:
        cells=lambda w: [{"label": f"{d}/{s}", "cell": c,
                          "parameters": cell_params(STUDIES[w.study], c, d, s, f"studies.{w.study}")}
                         for d, s, c in STUDY_CELLS[w.study]],
    priority: PRIORITY["summary"]
    log:
        "logs/studies/{study}/summary.log",
    conda:
        ENV
    script:
        "../scripts/study_summary.py"
