# Papers A and C, and the same EKF on other datasets (one job each: every scenario and run inside it).
PAPER_A = config["experiments"].get("paper_a")
PAPER_C = config["experiments"].get("paper_c")
PAPER_A_PAIRS = experiment_pairs(PAPER_A)
PAPER_C_PAIRS = experiment_pairs(PAPER_C)
GENERIC_EKF = config["experiments"].get("generic_ekf")
GENERIC_EKF_PAIRS = experiment_pairs(GENERIC_EKF)


rule paper_a:
    input:
        tables=all_tables(PAPER_A_PAIRS),
        campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in PAPER_A_PAIRS}),
        papers="config/papers.yaml",
    output:
        results="data/processed/paper_a/results.csv",
        claims="data/processed/paper_a/claims.json",
        cdf="data/processed/paper_a/figures/error_cdf.png",
        tracks="data/processed/paper_a/figures/trajectories.png",
        anchors="data/processed/paper_a/figures/rmse_vs_anchors.png",
    params:
        settings=PAPER_A,
        labels=[f"{d}/{s}" for d, s in PAPER_A_PAIRS],
        campaign_of={f"{d}/{s}": config["datasets"][d]["campaign"] for d, s in PAPER_A_PAIRS},
        tables_of={f"{d}/{s}": tables_of(d, s) for d, s in PAPER_A_PAIRS},
    priority: PRIORITY["estimator"]
    log:
        "logs/paper_a/paper_a.log",
    conda:
        ENV
    script:
        "../scripts/paper_a.py"


rule paper_c:
    input:
        tables=all_tables(PAPER_C_PAIRS),
        imu_5hz=[p for d, s in PAPER_C_PAIRS for p in imu_of(d, s)],
        campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in PAPER_C_PAIRS}),
        papers="config/papers.yaml",
    output:
        results="data/processed/paper_c/results.csv",
        claims="data/processed/paper_c/claims.json",
        histogram="data/processed/paper_c/figures/error_histogram.png",
        cdf="data/processed/paper_c/figures/error_cdf.png",
        tracks="data/processed/paper_c/figures/trajectories.png",
        anchors="data/processed/paper_c/figures/rmse_vs_anchors.png",
    params:
        settings=PAPER_C,
        labels=[f"{d}/{s}" for d, s in PAPER_C_PAIRS],
        campaign_of={f"{d}/{s}": config["datasets"][d]["campaign"] for d, s in PAPER_C_PAIRS},
        tables_of={f"{d}/{s}": tables_of(d, s) for d, s in PAPER_C_PAIRS},
        imu_of={f"{d}/{s}": imu_of(d, s) for d, s in PAPER_C_PAIRS},
    priority: PRIORITY["estimator"]
    log:
        "logs/paper_c/paper_c.log",
    conda:
        ENV
    script:
        "../scripts/paper_c.py"


rule generic_ekf:
    input:
        tables=all_tables(GENERIC_EKF_PAIRS),
        campaigns=sorted({config["datasets"][d]["campaign"] for d, _ in GENERIC_EKF_PAIRS}),
    output:
        results="data/processed/generic_ekf/results.csv",
    params:
        settings=GENERIC_EKF,
        labels=[f"{d}/{s}" for d, s in GENERIC_EKF_PAIRS],
        campaign_of={f"{d}/{s}": config["datasets"][d]["campaign"] for d, s in GENERIC_EKF_PAIRS},
        tables_of={f"{d}/{s}": tables_of(d, s) for d, s in GENERIC_EKF_PAIRS},
    log:
        "logs/generic_ekf/generic_ekf.log",
    conda:
        ENV
    script:
        "../scripts/generic_ekf.py"
