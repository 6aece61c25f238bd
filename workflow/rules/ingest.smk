# Raw logs -> one Parquet file per run and table, with a quarantine of unusable lines, and
# the IMU resampled in passing (~500 Hz -> uniform grid -> anti-aliasing low-pass -> 5 Hz);
# one job per shard of the scenario's runs. With one shard the job also writes the scenario's
# data summary (it holds all the runs). A run over the quarantine limits fails the job and
# leaves its quarantine table in logs/ingest/<job>/ (outputs of failed jobs are deleted).


rule ingest:
    input:
        raw=raw_inputs,
        campaign=campaign_file,
    output:
        tables=directory(f"data/processed/{{dataset}}/{{scenario}}/tables/{ONE_SHARD}"),
        imu_5hz=directory(f"data/processed/{{dataset}}/{{scenario}}/imu_5hz/{ONE_SHARD}"),
        **(SUMMARY_FILES if SUMMARY_IN_INGEST else {}),
    params:
        format=lambda w: config["datasets"][w.dataset]["format"],
        runs=lambda w: shard_runs(w),
        raw_dirs=lambda w: [raw_run_dir(config, w.dataset, w.scenario, r) for r in shard_runs(w)],
        max_quarantine_share=config["ingest"]["max_quarantine_share"],
        max_quarantine_share_per_file=config["ingest"]["max_quarantine_share_per_file"],
        resample=config["resample"],
        label="{dataset}/{scenario}",
    priority: PRIORITY["ingest"]
    log:
        f"logs/ingest/{{dataset}}-{{scenario}}-{ONE_SHARD}.log",
    conda:
        ENV
    script:
        "../scripts/ingest.py"
