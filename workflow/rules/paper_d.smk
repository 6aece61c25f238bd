# Paper D: Min-Max / multilateration, P-mix / F-mix, velocity tracking vs Kalman filter.


PAPER_D = config["experiments"].get("paper_d")
PAPER_D_PAIRS = paper_pairs("paper_d")


# One job runs every scenario over all its runs, then writes the paper's tables, claims, cost
# and figures over all of them (read back from the scenarios' files).
PAPER_D_FILES = scenario_files(PAPER_D_PAIRS, "paper_d", (("estimates", "parquet"), ("metrics", "csv"),
                                                         ("sensitivity", "csv")))


rule paper_d:
    input:
        tables=all_tables(PAPER_D_PAIRS),
        campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in PAPER_D_PAIRS}),
        papers="config/papers.yaml",
        nlos_campaign=sweep_campaign(PAPER_D, "nlos_sweep"),
        nlos_tables=sweep_tables(PAPER_D, "nlos_sweep"),
    output:
        **PAPER_D_FILES,
        results="data/processed/paper_d/results.csv",
        claims="data/processed/paper_d/claims.json",
        cost="data/processed/paper_d/cost.json",
        cdf=report("data/processed/paper_d/figures/error_cdf.png", category="Paper D", caption="../report/figure.rst"),
        tracks=report("data/processed/paper_d/figures/trajectories.png", category="Paper D", caption="../report/figure.rst"),
    params:
        spec=PAPER_D,
        sources=scenario_sources(PAPER_D_PAIRS),
        seed=config["seed"],
    priority: PRIORITY["paper"]
    log:
        "logs/paper_d/paper_d.log",
    conda:
        ENV
    script:
        "../scripts/paper_d.py"
