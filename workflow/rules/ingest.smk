# Raw logs -> one Parquet file per run and table, with a quarantine of unusable lines.


rule ingest:
    input:
        raw=raw_inputs,
        campaign=campaign_file,
    output:
        tables=directory("data/processed/{dataset}/{scenario}/tables"),
    params:
        format=lambda w: config["datasets"][w.dataset]["format"],
        runs=lambda w: dataset_runs(config, w.dataset, w.scenario),
        raw_dirs=lambda w: [
            raw_run_dir(config, w.dataset, w.scenario, r)
            for r in dataset_runs(config, w.dataset, w.scenario)
        ],
        max_quarantine_share=config["ingest"]["max_quarantine_share"],
    log:
        "logs/ingest/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/ingest.py"
