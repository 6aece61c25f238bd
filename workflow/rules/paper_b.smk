# Paper B: dead reckoning + UWB Min-Max fused by a steady-state KF (and the classical KF).


PAPER_B = config["experiments"].get("paper_b")
PAPER_B_PAIRS = paper_pairs("paper_b")   # a scenario listed both as measured and as simulated is run once


# Paper B's scenarios are short (a few seconds each, about half of it job start-up): one job
# runs them all, scenario after scenario, with each scenario's files as before, then writes
# the paper's tables, claims and figures over all of them (read back from those files).
PAPER_B_FILES = scenario_files(PAPER_B_PAIRS, "paper_b", (("estimates", "parquet"), ("metrics", "csv"),
                                                         ("sensitivity", "csv")))


rule paper_b:
    input:
        tables=all_tables(PAPER_B_PAIRS),
        imu_5hz=[p for d, s in PAPER_B_PAIRS for p in imu_of(d, s)],
        campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in PAPER_B_PAIRS}),
        papers="config/papers.yaml",
        nlos_campaign=sweep_campaign(PAPER_B, "nlos_sweep"),
        nlos_tables=sweep_tables(PAPER_B, "nlos_sweep"),
        snr_campaign=[config["datasets"][d]["campaign"] for d, _ in experiment_pairs(PAPER_B, "simulation_scenarios")[:1]],
    output:
        **PAPER_B_FILES,
        results="data/processed/paper_b/results.csv",
        claims="data/processed/paper_b/claims.json",
        tracks=report("data/processed/paper_b/figures/trajectories.png", category="Paper B", caption="../report/figure.rst"),
        errors=report("data/processed/paper_b/figures/error_over_time.png", category="Paper B", caption="../report/figure.rst"),
        cdf=report("data/processed/paper_b/figures/error_cdf.png", category="Paper B", caption="../report/figure.rst"),
        snr=report("data/processed/paper_b/figures/dr_rmse_vs_snr.png", category="Paper B", caption="../report/figure.rst"),
    params:
        spec=PAPER_B,
        simulated=[f"{d}/{s}" for d, s in experiment_pairs(PAPER_B, "simulation_scenarios")],
        sources=scenario_sources(PAPER_B_PAIRS),
        snr_curve=PAPER_B.get("snr_curve", {"runs": 0}) if PAPER_B else {"runs": 0},
        snr_scenario=next((f"{d}/{s}" for d, s in experiment_pairs(PAPER_B, "simulation_scenarios")), ""),
        seed=config["seed"],
        resample=config["resample"],
    priority: PRIORITY["last_paper"]
    log:
        "logs/paper_b/paper_b.log",
    conda:
        ENV
    script:
        "../scripts/paper_b.py"
