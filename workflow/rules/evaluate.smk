# Data quality against ground truth (inventory, quarantine, range error, path-loss fit, IMU
# resampling): one job per dataset over all its scenarios and shards, after their ingest. It
# is not part of the ingest job, so the estimators wait for the tables only and the summary
# (with its figures, about half of what an ingest job did) runs beside them.

for _dataset, _spec in config["datasets"].items():
    _summaries = [{"label": f"{_dataset}/{s}", "tables": tables_of(_dataset, s), "imu_5hz": imu_of(_dataset, s),
                   "outputs": {name: path.format(dataset=_dataset, scenario=s) for name, path in SUMMARY_FILES.items()}}
                  for s in _spec["scenarios"]]

    rule:
        name:
            f"summarize_{_dataset}".replace("-", "_")
        input:
            tables=[p for task in _summaries for p in task["tables"]],
            imu_5hz=[p for task in _summaries for p in task["imu_5hz"]],
            campaign=_spec["campaign"],
        output:
            [path for task in _summaries for path in task["outputs"].values()],
        params:
            tasks=_summaries,
        priority: PRIORITY["data_summary"]
        log:
            f"logs/summarize_data/{_dataset}.log",
        conda:
            ENV
        script:
            "../scripts/summarize_data.py"
