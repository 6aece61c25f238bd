# The HTML report, reports/index.html (the summary) with reports/pages/ (a page per study, paper
# and dataset, provenance, and the figures they share), and the results contract (reports/results.csv).
# The page, results.csv and the papers' figures are also registered with Snakemake's
# report(), so `snakemake --report report.zip` packages them with the run's provenance.
report: "../report/workflow.rst"

import glob

STUDY_OUTPUTS = ["results.csv", "figures/error_cdf.png", "figures/error_over_time.png", "figures/trajectories.png",
                 "figures/pcrb_vs_rmse.png", "figures/consistency.png", "figures/estimators.png"]


rule report:
    input:
        summaries=scenario_outputs("data/processed/{dataset}/{scenario}/data_summary.json"),
        results=scenario_outputs("data/processed/{dataset}/{scenario}/data_results.csv"),
        figures=scenario_outputs("data/processed/{dataset}/{scenario}/figures/range_error.png")
        + scenario_outputs("data/processed/{dataset}/{scenario}/figures/rss_distance.png")
        + scenario_outputs("data/processed/{dataset}/{scenario}/figures/imu_resampling.png"),
        floor_plans=[f"data/processed/{d}/figures/floor_plan.png" for d in config["datasets"]],
        templates=sorted(glob.glob("workflow/templates/*.html.j2")),
        papers="config/papers.yaml",
        paper_a=(
            [
                "data/processed/paper_a/results.csv",
                "data/processed/paper_a/claims.json",
                "data/processed/paper_a/figures/error_cdf.png",
                "data/processed/paper_a/figures/trajectories.png",
                "data/processed/paper_a/figures/rmse_vs_anchors.png",
                "data/processed/paper_a/figures/pcrb_vs_rmse.png",
                "data/processed/paper_a/figures/consistency.png",
                "data/processed/paper_a/figures/gain_vs_static_share.png",
            ]
            if PAPER_A_PAIRS
            else []
        ),
        paper_c=(
            [
                "data/processed/paper_c/results.csv",
                "data/processed/paper_c/claims.json",
                "data/processed/paper_c/figures/error_histogram.png",
                "data/processed/paper_c/figures/error_cdf.png",
                "data/processed/paper_c/figures/trajectories.png",
                "data/processed/paper_c/figures/rmse_vs_anchors.png",
                "data/processed/paper_c/figures/pcrb_vs_rmse.png",
                "data/processed/paper_c/figures/consistency.png",
                "data/processed/paper_c/figures/rmse_vs_noise.png",
            ]
            if PAPER_C_PAIRS
            else []
        ),
        studies=[f"data/processed/studies/{study}/{name}" for study in STUDIES for name in STUDY_OUTPUTS],
        ranging=RANGING_OUTPUTS,
        bounds=[f"data/processed/{d}/bounds/{name}" for d in BOUND_DATASETS
                for name in ("results.csv", "figures/crlb_maps.png")]
        + [f"data/processed/{d}/{s}/bounds/subset_monte_carlo.csv" for d, s in SUBSET_MONTE_CARLO],
        paper_b=(
            [
                "data/processed/paper_b/results.csv",
                "data/processed/paper_b/claims.json",
                "data/processed/paper_b/figures/trajectories.png",
                "data/processed/paper_b/figures/error_over_time.png",
                "data/processed/paper_b/figures/error_cdf.png",
                "data/processed/paper_b/figures/dr_rmse_vs_snr.png",
            ]
            if PAPER_B_PAIRS
            else []
        ),
        paper_d=(
            [
                "data/processed/paper_d/results.csv",
                "data/processed/paper_d/claims.json",
                "data/processed/paper_d/cost.json",
                "data/processed/paper_d/figures/error_cdf.png",
                "data/processed/paper_d/figures/trajectories.png",
            ]
            if PAPER_D_PAIRS
            else []
        ),
    output:
        html=report("reports/index.html", category="Report", caption="../report/page.rst"),
        results=report("reports/results.csv", category="Report", caption="../report/page.rst"),
        pages=report(directory("reports/pages"), category="Report", htmlindex="provenance.html",
                     caption="../report/page.rst"),   # a page per study, paper and dataset, provenance; their figures
    params:
        config=config,
        paper_d_labels=[f"{d}/{s}" for d, s in PAPER_D_PAIRS],
        paper_b_labels=[f"{d}/{s}" for d, s in PAPER_B_PAIRS],
        paper_a_labels=[f"{d}/{s}" for d, s in PAPER_A_PAIRS],
        paper_c_labels=[f"{d}/{s}" for d, s in PAPER_C_PAIRS],
        studies=STUDIES,
    log:
        "logs/report/report.log",
    conda:
        ENV
    script:
        "../scripts/report.py"
