# IMU: ~500 Hz raw samples -> uniform grid -> anti-aliasing low-pass -> 5 Hz.


rule resample:
    input:
        tables="data/processed/{dataset}/{scenario}/tables",
    output:
        imu_5hz=directory("data/processed/{dataset}/{scenario}/imu_5hz"),
    params:
        **config["resample"],
    log:
        "logs/resample/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/resample.py"
