# IMU: ~500 Hz raw samples -> uniform grid -> anti-aliasing low-pass -> 5 Hz (per shard).


rule resample:
    input:
        tables="data/processed/{dataset}/{scenario}/tables/{shard}",
    output:
        imu_5hz=directory("data/processed/{dataset}/{scenario}/imu_5hz/{shard}"),
    params:
        **config["resample"],
    priority: PRIORITY["ingest"]
    log:
        "logs/resample/{dataset}-{scenario}-{shard}.log",
    conda:
        ENV
    script:
        "../scripts/resample.py"
