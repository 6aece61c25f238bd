# Data quality against ground truth: inventory, quarantine, range error, path-loss fit. With
# one shard per scenario the ingest job writes it; with more,
# this rule reads the tables of all the scenario's shards.

if not SUMMARY_IN_INGEST:

    rule summarize_data:
        input:
            tables=lambda w: tables_of(w.dataset, w.scenario),
            imu_5hz=lambda w: imu_of(w.dataset, w.scenario),
            campaign=campaign_file,
        output:
            **SUMMARY_FILES,
        params:
            label="{dataset}/{scenario}",
        priority: PRIORITY["ingest"]
        log:
            "logs/summarize_data/{dataset}-{scenario}.log",
        conda:
            ENV
        script:
            "../scripts/summarize_data.py"
