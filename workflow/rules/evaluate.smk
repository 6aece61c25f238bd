# Data quality against ground truth: inventory, quarantine, range error, path-loss fit.


rule summarize_data:
    input:
        tables=lambda w: tables_of(w.dataset, w.scenario),
        imu_5hz=lambda w: imu_of(w.dataset, w.scenario),
        campaign=campaign_file,
    output:
        summary="data/processed/{dataset}/{scenario}/data_summary.json",
        results="data/processed/{dataset}/{scenario}/data_results.csv",
        range_error="data/processed/{dataset}/{scenario}/figures/range_error.png",
        rss="data/processed/{dataset}/{scenario}/figures/rss_distance.png",
        imu="data/processed/{dataset}/{scenario}/figures/imu_resampling.png",
    params:
        label="{dataset}/{scenario}",
    log:
        "logs/summarize_data/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/summarize_data.py"
