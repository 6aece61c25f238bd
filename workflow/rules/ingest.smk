# Raw logs -> one Parquet file per run and table, with a quarantine of unusable lines, and
# the IMU resampled in passing (~500 Hz -> uniform grid -> anti-aliasing low-pass -> 5 Hz).
# The data summary is a job of its own (evaluate.smk), so the estimators wait for the tables only.
# A run over the quarantine limits fails the job and leaves its quarantine table in
# logs/ingest/<job>/ (outputs of failed jobs are deleted).
#
# Simulated logs: one job per format and shard over every simulated scenario of that format,
# as the simulation job that writes them (each job pays its start-up once, not per scenario).
# Its input is the simulation job's run folders (a few dozen paths, not every log file): a
# simulated log edited by hand is ingested again with `--forcerun <job>`.
# Real logs: one job per scenario and shard (rule ingest), with every raw file as an input,
# so that new or edited logs of one scenario re-ingest only that scenario.

INGEST_PARAMS = {
    "limits": {"per_run": config["ingest"]["max_quarantine_share"],
               "per_file": config["ingest"]["max_quarantine_share_per_file"]},
    "resample": config["resample"],
}

for _format, _pairs in SIMULATED_PAIRS.items():
    for _shard in simulated_shards(config) if _pairs else []:
        _here = [(d, s) for d, s in _pairs if _shard in shards_of(config, d, s)]   # scenarios with runs in this shard
        _tasks = [ingest_task(d, s, _shard, f"logs/ingest/{_format}-{_shard}/{d}-{s}") for d, s in _here]

        rule:
            name:
                f"ingest_{_format}_{_shard.replace('-', '')}"
            input:
                raw=[raw_run_dir(config, d, s, run) for d, s in _here for run in shards_of(config, d, s)[_shard]],
                campaigns=sorted({task["campaign"] for task in _tasks}),
            output:
                tables=[directory(task["tables"]) for task in _tasks],
                imu_5hz=[directory(task["imu_5hz"]) for task in _tasks],
            params:
                tasks=_tasks,
                **INGEST_PARAMS,
            priority: PRIORITY["ingest"]
            log:
                f"logs/ingest/{_format}-{_shard}.log",
            conda:
                ENV
            script:
                "../scripts/ingest.py"


rule ingest:
    wildcard_constraints:
        dataset=REAL_DATASETS,
    input:
        raw=raw_inputs,
        campaign=campaign_file,
    output:
        tables=directory("data/processed/{dataset}/{scenario}/tables/{shard}"),
        imu_5hz=directory("data/processed/{dataset}/{scenario}/imu_5hz/{shard}"),
    params:
        tasks=lambda w: [ingest_task(w.dataset, w.scenario, w.shard, f"logs/ingest/{w.dataset}-{w.scenario}-{w.shard}")],
        **INGEST_PARAMS,
    priority: PRIORITY["ingest"]
    log:
        "logs/ingest/{dataset}-{scenario}-{shard}.log",
    conda:
        ENV
    script:
        "../scripts/ingest.py"
