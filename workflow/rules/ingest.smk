# Raw logs -> one Parquet file per run and table, with a quarantine of unusable lines, and
# the IMU resampled in passing (~500 Hz -> uniform grid -> anti-aliasing low-pass -> 5 Hz);
# one job per shard of the scenario's runs. A run over the quarantine limits fails the job
# and leaves its quarantine table in logs/ingest/<job>/ (outputs of failed jobs are deleted).


rule ingest:
    input:
        raw=raw_inputs,
        campaign=campaign_file,
    output:
        tables=directory("data/processed/{dataset}/{scenario}/tables/{shard}"),
        imu_5hz=directory("data/processed/{dataset}/{scenario}/imu_5hz/{shard}"),
    params:
        format=lambda w: config["datasets"][w.dataset]["format"],
        runs=lambda w: shard_runs(w),
        raw_dirs=lambda w: [raw_run_dir(config, w.dataset, w.scenario, r) for r in shard_runs(w)],
        max_quarantine_share=config["ingest"]["max_quarantine_share"],
        max_quarantine_share_per_file=config["ingest"]["max_quarantine_share_per_file"],
        resample=config["resample"],
    priority: PRIORITY["ingest"]
    log:
        "logs/ingest/{dataset}-{scenario}-{shard}.log",
    conda:
        ENV
    script:
        "../scripts/ingest.py"
