# Paper B: dead reckoning + UWB Min-Max fused by a steady-state KF (and the classical KF).


PAPER_B = config["experiments"].get("paper_b")
PAPER_B_PAIRS = experiment_pairs(PAPER_B) + experiment_pairs(PAPER_B, "simulation_scenarios")


rule paper_b:
    input:
        tables=lambda w: tables_of(w.dataset, w.scenario),
        imu_5hz=lambda w: imu_of(w.dataset, w.scenario),
        campaign=campaign_file,
    output:
        estimates="data/processed/{dataset}/{scenario}/paper_b/estimates.parquet",
        metrics="data/processed/{dataset}/{scenario}/paper_b/metrics.csv",
        sensitivity="data/processed/{dataset}/{scenario}/paper_b/sensitivity.csv",
    params:
        settings=PAPER_B,
        simulated=lambda w: f"{w.dataset}/{w.scenario}" in PAPER_B["simulation_scenarios"],
    priority: PRIORITY["summary"]
    log:
        "logs/paper_b/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/paper_b.py"


rule paper_b_summary:
    input:
        metrics=[f"data/processed/{d}/{s}/paper_b/metrics.csv" for d, s in PAPER_B_PAIRS],
        sensitivity=[f"data/processed/{d}/{s}/paper_b/sensitivity.csv" for d, s in PAPER_B_PAIRS],
        estimates=[f"data/processed/{d}/{s}/paper_b/estimates.parquet" for d, s in PAPER_B_PAIRS],
        papers="config/papers.yaml",
        nlos_campaign=sweep_campaign(PAPER_B, "nlos_sweep"),
        nlos_tables=sweep_tables(PAPER_B, "nlos_sweep"),
        snr_campaign=[config["datasets"][d]["campaign"] for d, _ in experiment_pairs(PAPER_B, "simulation_scenarios")[:1]],
    output:
        results="data/processed/paper_b/results.csv",
        snr=report("data/processed/paper_b/figures/dr_rmse_vs_snr.png", category="Paper B", caption="../report/figure.rst"),
        claims="data/processed/paper_b/claims.json",
        tracks=report("data/processed/paper_b/figures/trajectories.png", category="Paper B", caption="../report/figure.rst"),
        errors=report("data/processed/paper_b/figures/error_over_time.png", category="Paper B", caption="../report/figure.rst"),
        cdf=report("data/processed/paper_b/figures/error_cdf.png", category="Paper B", caption="../report/figure.rst"),
    params:
        labels=[f"{d}/{s}" for d, s in PAPER_B_PAIRS],
        simulated=[f"{d}/{s}" for d, s in experiment_pairs(PAPER_B, "simulation_scenarios")],
        settings=PAPER_B,
        snr_curve=PAPER_B.get("snr_curve", {"runs": 0}) if PAPER_B else {"runs": 0},
        snr_scenario=next((f"{d}/{s}" for d, s in experiment_pairs(PAPER_B, "simulation_scenarios")), ""),
        seed=config["seed"],
        resample=config["resample"],
    priority: PRIORITY["summary"]
    log:
        "logs/paper_b/summary.log",
    conda:
        ENV
    script:
        "../scripts/paper_b_summary.py"
