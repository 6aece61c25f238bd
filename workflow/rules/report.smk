# The HTML report, reports/index.html (the summary) with reports/pages/ (a page per study, paper
# and dataset, provenance, and the figures they share), and the results contract (reports/results.csv).
# The page, results.csv and the papers' figures are also registered with Snakemake's
# report(), so `snakemake --report report.zip` packages them with the run's provenance.
report: "../report/workflow.rst"

import glob
import os

from wsnloc import experiments as _experiments

EXPERIMENTS_DIR = os.path.relpath(Path(_experiments.__file__).parent)   # src/wsnloc/experiments
PAPERS = ("paper_a", "paper_b", "paper_c", "paper_d")   # the papers' rules (their sections in this order)

STUDY_OUTPUTS = ["results.csv", "diagnosis.csv", "figures/error_cdf.png", "figures/error_over_time.png", "figures/trajectories.png",
                 "figures/height_over_time.png", "figures/pcrb_vs_rmse.png", "figures/consistency.png", "figures/estimators.png"]


rule report:
    input:
        summaries=scenario_outputs("data/processed/{dataset}/{scenario}/data_summary.json"),
        results=scenario_outputs("data/processed/{dataset}/{scenario}/data_results.csv"),
        figures=scenario_outputs("data/processed/{dataset}/{scenario}/figures/range_error.png")
        + scenario_outputs("data/processed/{dataset}/{scenario}/figures/rss_distance.png")
        + scenario_outputs("data/processed/{dataset}/{scenario}/figures/imu_resampling.png"),
        floor_plans=[f"data/processed/{d}/figures/floor_plan.png" for d in config["datasets"]],
        templates=sorted(glob.glob("workflow/templates/*.html.j2")),
        partials=sorted(glob.glob(f"{EXPERIMENTS_DIR}/paper_*/section.html.j2")),   # each paper's set-up note
        papers="config/papers.yaml",
        studies=[f"data/processed/studies/{study}/{name}" for study in STUDIES for name in STUDY_OUTPUTS],
        ranging=RANGING_OUTPUTS,
        bounds=[f"data/processed/{d}/bounds/{name}" for d in BOUND_DATASETS
                for name in ("results.csv", "figures/crlb_maps.png")]
        + [f"data/processed/{d}/{s}/bounds/subset_monte_carlo.csv" for d, s in SUBSET_MONTE_CARLO],
        paper_files=[path for paper in PAPERS for path in paper_outputs(paper)],
    output:
        html=report("reports/index.html", category="Report", caption="../report/page.rst"),
        results=report("reports/results.csv", category="Report", caption="../report/page.rst"),
        pages=report(directory("reports/pages"), category="Report", htmlindex="provenance.html",
                     caption="../report/page.rst"),   # a page per study, paper and dataset, provenance; their figures
    params:
        config=config,
        papers={paper: [f"{d}/{s}" for d, s in paper_pairs(paper)] for paper in PAPERS if paper_pairs(paper)},
        studies=STUDIES,
    log:
        "logs/report/report.log",
    conda:
        ENV
    script:
        "../scripts/report.py"
