# Papers A and C: one job per paper (each job pays its start-up once).
PAPER_A = config["experiments"].get("paper_a")
PAPER_C = config["experiments"].get("paper_c")
PAPER_A_PAIRS = paper_pairs("paper_a")
PAPER_C_PAIRS = paper_pairs("paper_c")


# Paper A: one job runs every scenario over all its runs, then writes the paper's tables,
# claims and figures over all of them (read back from the scenarios' files).
PAPER_A_FILES = scenario_files(PAPER_A_PAIRS, "paper_a", (("estimates", "parquet"), ("metrics", "csv"),
                                                         ("quality", "parquet"), ("sensitivity", "csv")))


rule paper_a:
    input:
        tables=all_tables(PAPER_A_PAIRS),
        campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in PAPER_A_PAIRS}),
        papers="config/papers.yaml",
        sweep_campaign=sweep_campaign(PAPER_A, "static_sweep"),
    output:
        **PAPER_A_FILES,
        results="data/processed/paper_a/results.csv",
        claims="data/processed/paper_a/claims.json",
        cdf=report("data/processed/paper_a/figures/error_cdf.png", category="Paper A", caption="../report/figure.rst"),
        tracks=report("data/processed/paper_a/figures/trajectories.png", category="Paper A", caption="../report/figure.rst"),
        anchors=report("data/processed/paper_a/figures/rmse_vs_anchors.png", category="Paper A", caption="../report/figure.rst"),
        static=report("data/processed/paper_a/figures/gain_vs_static_share.png", category="Paper A", caption="../report/figure.rst"),
        bounds=report("data/processed/paper_a/figures/pcrb_vs_rmse.png", category="Paper A", caption="../report/figure.rst"),
        consistency=report("data/processed/paper_a/figures/consistency.png", category="Paper A", caption="../report/figure.rst"),
    params:
        spec=PAPER_A,
        sources=scenario_sources(PAPER_A_PAIRS),
        seed=config["seed"],
    priority: PRIORITY["paper"]
    log:
        "logs/paper_a/paper_a.log",
    conda:
        ENV
    script:
        "../scripts/paper_a.py"


# Paper C's scenarios are short (a few seconds each, about half of it job start-up): one job
# runs them all, scenario after scenario, with each scenario's files as before, then writes
# the paper's tables, claims and figures over all of them (read back from those files).
PAPER_C_FILES = scenario_files(PAPER_C_PAIRS, "paper_c", (("estimates", "parquet"), ("metrics", "csv"),
                                                         ("quality", "parquet"), ("sensitivity", "csv")))


rule paper_c:
    input:
        tables=all_tables(PAPER_C_PAIRS),
        imu_5hz=[p for d, s in PAPER_C_PAIRS for p in imu_of(d, s)],
        campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in PAPER_C_PAIRS}),
        papers="config/papers.yaml",
    output:
        **PAPER_C_FILES,
        results="data/processed/paper_c/results.csv",
        claims="data/processed/paper_c/claims.json",
        histogram=report("data/processed/paper_c/figures/error_histogram.png", category="Paper C", caption="../report/figure.rst"),
        cdf=report("data/processed/paper_c/figures/error_cdf.png", category="Paper C", caption="../report/figure.rst"),
        tracks=report("data/processed/paper_c/figures/trajectories.png", category="Paper C", caption="../report/figure.rst"),
        anchors=report("data/processed/paper_c/figures/rmse_vs_anchors.png", category="Paper C", caption="../report/figure.rst"),
        noise=report("data/processed/paper_c/figures/rmse_vs_noise.png", category="Paper C", caption="../report/figure.rst"),
        bounds=report("data/processed/paper_c/figures/pcrb_vs_rmse.png", category="Paper C", caption="../report/figure.rst"),
        consistency=report("data/processed/paper_c/figures/consistency.png", category="Paper C", caption="../report/figure.rst"),
    params:
        spec=PAPER_C,
        sources=scenario_sources(PAPER_C_PAIRS),
    priority: PRIORITY["paper"]
    log:
        "logs/paper_c/paper_c.log",
    conda:
        ENV
    script:
        "../scripts/paper_c.py"
