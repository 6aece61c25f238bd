# Paper D: Min-Max / multilateration, P-mix / F-mix, velocity tracking vs Kalman filter.


PAPER_D = config["experiments"].get("paper_d")
PAPER_D_PAIRS = experiment_pairs(PAPER_D)


rule paper_d:
    input:
        tables=lambda w: tables_of(w.dataset, w.scenario),
        campaign=campaign_file,
    output:
        estimates="data/processed/{dataset}/{scenario}/paper_d/estimates.parquet",
        metrics="data/processed/{dataset}/{scenario}/paper_d/metrics.csv",
        sensitivity="data/processed/{dataset}/{scenario}/paper_d/sensitivity.csv",
    params:
        settings=PAPER_D,
    priority: PRIORITY["paper"]
    log:
        "logs/paper_d/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/paper_d.py"


rule paper_d_summary:
    input:
        metrics=[f"data/processed/{d}/{s}/paper_d/metrics.csv" for d, s in PAPER_D_PAIRS],
        sensitivity=[f"data/processed/{d}/{s}/paper_d/sensitivity.csv" for d, s in PAPER_D_PAIRS],
        estimates=[f"data/processed/{d}/{s}/paper_d/estimates.parquet" for d, s in PAPER_D_PAIRS],
        papers="config/papers.yaml",
        nlos_campaign=sweep_campaign(PAPER_D, "nlos_sweep"),
        nlos_tables=sweep_tables(PAPER_D, "nlos_sweep"),
    output:
        results="data/processed/paper_d/results.csv",
        claims="data/processed/paper_d/claims.json",
        cost="data/processed/paper_d/cost.json",
        cdf=report("data/processed/paper_d/figures/error_cdf.png", category="Paper D", caption="../report/figure.rst"),
        tracks=report("data/processed/paper_d/figures/trajectories.png", category="Paper D", caption="../report/figure.rst"),
    params:
        settings=PAPER_D,
        labels=[f"{d}/{s}" for d, s in PAPER_D_PAIRS],
        seed=config["seed"],
    priority: PRIORITY["summary"]
    log:
        "logs/paper_d/summary.log",
    conda:
        ENV
    script:
        "../scripts/paper_d_summary.py"
