# Public datasets converted into the generic format by the workflow (datasets with `convert:
# {dataset, source}`): one job per dataset writes every run's tables under its raw_dir; the runs
# are known from the source's layout (wsnloc.io.convert.run_names), so the ingest and study jobs
# are planned before the conversion runs. A dataset whose source is absent was dropped with a
# message before validation (wsnloc.workflow.without_missing_sources).
from wsnloc.io.convert import RUN_FILES

CONVERTED = {d: spec for d, spec in config["datasets"].items() if spec.get("convert")}


def converted_files(dataset):
    """The raw files the conversion of a dataset writes (every run of every scenario)."""
    converter = CONVERTED[dataset]["convert"]["dataset"]
    return [f"{raw_run_dir(config, dataset, s, run)}/{name}" for s in config["datasets"][dataset]["scenarios"]
            for run in dataset_runs(config, dataset, s) for name in RUN_FILES[converter]]


for _dataset, _spec in CONVERTED.items():

    rule:
        name:
            f"convert_{_dataset}"
        input:
            source=sorted(str(p) for p in Path(_spec["convert"]["source"]).rglob("*") if p.is_file()),
        output:
            converted_files(_dataset),
        params:
            dataset=_spec["convert"]["dataset"],
            source=_spec["convert"]["source"],
            raw_dir=_spec["raw_dir"],
        priority: PRIORITY["ingest"] + 1
        log:
            f"logs/convert/{_dataset}.log",
        conda:
            ENV
        script:
            "../scripts/convert.py"
