# Helpers shared by the rules: which datasets, scenarios and runs exist, and where.
from pathlib import Path


from wsnloc.estimators import registry as _registry
from wsnloc.io.convert import RUN_FILES
from wsnloc.studies import cell_params, estimator_of, reads_rss, runs_on, study_cells
from wsnloc.workflow import (
    dataset_runs,
    processed_dirs,
    raw_run_dir,
    scenario_pairs,
    shards_of,
    simulated_shards,
)

# Each job runs its script (workflow/scripts/, with Snakemake's `script`) in the software
# environment below when Snakemake manages them (`--sdm conda`), else in Snakemake's own.
ENV = "../envs/wsnloc.yaml"


# Job order on few cores (higher first among ready jobs): the data chain (simulate, ingest)
# first, Newcom++ before Cricket, so that every estimator job is ready early; then the study
# scenario jobs (the longest, about twice paper A: started last, one of them was the build's
# serial tail), then papers A, C and D (5-15 s each: estimators, then tables and figures) and
# the geometry job (floor plans, static bounds). The study summaries wait for their scenarios:
# paper B, the shortest paper job, comes last so that it runs beside them instead of leaving a
# core idle before the report. The data summaries run beside the papers: the ranging validation
# waits for them, so a summary left to the end made a chain of two jobs before the report.
# Opt-in analyses (subset Monte Carlo) run after the papers.
PRIORITY = {"simulate_newcom": 6, "simulate_cricket": 5, "ingest": 5, "study": 5, "paper": 4, "geometry": 4,
            "data_summary": 4, "opt_in": 3, "summary": 2, "last_paper": 2}
RAW_FILES = {"newcom": ["uwb.log", "zigbee.log", "imu.log", "truth.log"],
             "cricket": ["listener.log", "imu.log", "truth.log"]}
SIMULATED = [name for name, d in config["datasets"].items() if d["source"] == "simulate"]
PAIRS = scenario_pairs(config)
# Simulated scenarios by format ({format: [(dataset, scenario)]}): one simulation job and one
# ingest job per format and shard cover them all, since a format's logs are written together.
SIMULATED_PAIRS = {fmt: [(d, s) for d, s in PAIRS if d in SIMULATED and config["datasets"][d]["format"] == fmt]
                   for fmt in ("newcom", "cricket")}
# Real-log datasets: one ingest job per scenario and shard (rule ingest); never-matching when none.
REAL_DATASETS = "|".join(d for d in config["datasets"] if d not in SIMULATED) or "(?!)"


wildcard_constraints:
    dataset="|".join(config["datasets"]) or "^$",
    scenario=r"[A-Za-z0-9_-]+",
    shard=r"shard-\d+",


def shard_runs(wildcards):
    """The runs of one shard of a scenario."""
    return shards_of(config, wildcards.dataset, wildcards.scenario)[wildcards.shard]


def tables_of(dataset, scenario):
    return processed_dirs(config, dataset, scenario, "tables")


def imu_of(dataset, scenario):
    return processed_dirs(config, dataset, scenario, "imu_5hz")


def raw_files(dataset, scenario, runs):
    """Raw files of the given runs of a scenario (simulated or real; generic: what is there)."""
    fmt = config["datasets"][dataset]["format"]
    files = []
    for run in runs:
        run_dir = raw_run_dir(config, dataset, scenario, run)
        if config["datasets"][dataset].get("convert"):      # written by the conversion rule (convert.smk)
            files += [f"{run_dir}/{name}" for name in RUN_FILES[config["datasets"][dataset]["convert"]["dataset"]]]
        elif fmt == "generic":
            files += sorted(str(p) for p in Path(run_dir).iterdir() if p.suffix in (".csv", ".parquet"))
        else:
            files += [f"{run_dir}/{name}" for name in RAW_FILES[fmt]]
    return files


def raw_inputs(wildcards):
    """Raw files of the runs of one shard of the wildcards' scenario."""
    return raw_files(wildcards.dataset, wildcards.scenario, shard_runs(wildcards))


def campaign_file(wildcards):
    return config["datasets"][wildcards.dataset]["campaign"]


# The data summary of a scenario (rule summarize_<dataset>, evaluate.smk).
SUMMARY_FILES = {
    "summary": "data/processed/{dataset}/{scenario}/data_summary.json",
    "results": "data/processed/{dataset}/{scenario}/data_results.csv",
    "range_error": "data/processed/{dataset}/{scenario}/figures/range_error.png",
    "rss": "data/processed/{dataset}/{scenario}/figures/rss_distance.png",
    "imu": "data/processed/{dataset}/{scenario}/figures/imu_resampling.png",
}


def ingest_task(dataset, scenario, shard, keep_dir):
    """One scenario's shard in an ingest job (read by workflow/scripts/ingest.py): its format,
    campaign, runs and their raw folders, its table and 5 Hz IMU folders and where a failed
    run's quarantine is kept."""
    runs = shards_of(config, dataset, scenario)[shard]
    spec = config["datasets"][dataset]
    return {"label": f"{dataset}/{scenario}", "format": spec["format"], "campaign": spec["campaign"], "runs": runs,
            "raw_dirs": [raw_run_dir(config, dataset, scenario, run) for run in runs],
            "tables": f"data/processed/{dataset}/{scenario}/tables/{shard}",
            "imu_5hz": f"data/processed/{dataset}/{scenario}/imu_5hz/{shard}",
            "keep_dir": keep_dir}


def experiment_pairs(spec, key="scenarios"):
    """(dataset, scenario) pairs an experiment runs on; none when it is not configured."""
    return [tuple(label.split("/", 1)) for label in spec.get(key, [])] if spec else []


def paper_pairs(paper):
    """(dataset, scenario) pairs of a paper (config experiments.<paper>): its scenarios, then its
    simulation scenarios (paper B) not among them; none when it is not configured."""
    spec = config["experiments"].get(paper)
    return list(dict.fromkeys(experiment_pairs(spec) + experiment_pairs(spec, "simulation_scenarios")))


def paper_outputs(paper):
    """The paper job's outputs the report reads (results.csv, claims.json, cost.json, figures: those
    under data/processed/<paper>/, in the order its rule declares them); none when not configured."""
    if not paper_pairs(paper):
        return []
    return [path for path in getattr(rules, paper).output if path.startswith(f"data/processed/{paper}/")]


def scenario_outputs(pattern):
    """Expand a per-scenario path pattern over every (dataset, scenario) pair."""
    return [pattern.format(dataset=d, scenario=s) for d, s in PAIRS]


def all_tables(pairs):
    return [p for d, s in pairs for p in tables_of(d, s)]


def scenario_files(pairs, experiment, files):
    """{name: [data/processed/<dataset>/<scenario>/<experiment>/<name>.<ext> per pair]} for
    files = ((name, ext), ...): the per-scenario outputs of a job over several scenarios."""
    return {name: [f"data/processed/{d}/{s}/{experiment}/{name}.{ext}" for d, s in pairs] for name, ext in files}


def scenario_sources(pairs):
    """Params of a job over several scenarios (read by wsnloc.workflow.each_scenario): the
    labels in order and, per label, its table and 5 Hz IMU folders and its campaign file."""
    labels = [f"{d}/{s}" for d, s in pairs]
    return {"labels": labels,
            "tables_of": dict(zip(labels, (tables_of(d, s) for d, s in pairs))),
            "imu_of": dict(zip(labels, (imu_of(d, s) for d, s in pairs))),
            "campaign_of": dict(zip(labels, (config["datasets"][d]["campaign"] for d, s in pairs)))}


# ---- studies ----
STUDIES = config.get("studies") or {}
STUDY_CELLS = study_cells(config)   # study: [(dataset, scenario, cell)]


def study_scenario_cells(w):
    """Every cell of the study on one scenario: name, estimator and resolved parameters (the
    scenario job's Snakemake params: a changed parameter re-runs its scenario's job)."""
    spec = STUDIES[w.study]
    return [{"cell": cell, "estimator": estimator_of(spec, cell),
             "parameters": cell_params(spec, cell, w.dataset, w.scenario, f"studies.{w.study}")}
            for cell in spec["estimators"] if runs_on(spec, cell, f"{w.dataset}/{w.scenario}")]


def study_scenario_inputs(w):
    """Tables of the scenario (+ 5 Hz IMU when a cell reads it), and calibration donors (RSS or
    ranges) of the same dataset when the scenario has a single run and a cell calibrates."""
    cells = study_scenario_cells(w)
    inputs = {"tables": tables_of(w.dataset, w.scenario), "campaign": campaign_file(w), "donors": []}
    if any("imu_5hz" in _registry.get(c["estimator"]).tables(c["parameters"]) for c in cells):
        inputs["imu_5hz"] = imu_of(w.dataset, w.scenario)
    single = len(dataset_runs(config, w.dataset, w.scenario)) < 2
    calibrates = any(reads_rss(c["estimator"], c["parameters"]) or c["parameters"].get("range_calibration") == "other_run"
                     for c in cells)
    if single and calibrates:
        inputs["donors"] = [p for s in config["datasets"][w.dataset]["scenarios"] if s != w.scenario
                            for p in tables_of(w.dataset, s)]
    return inputs


def study_references(w):
    """What a study's summary needs for its real-data references (`references: true`): per
    scenario its label, campaign file, and per run its raw folder (the published tracks stored
    beside the run) and table folder (wsnloc.experiments.realdata); [] when off."""
    spec = STUDIES[w.study]
    if not spec.get("references"):
        return []
    out = []
    for label in spec["scenarios"]:
        dataset, scenario = label.split("/", 1)
        runs = dataset_runs(config, dataset, scenario)
        shard_of = {run: shard for shard, members in shards_of(config, dataset, scenario).items() for run in members}
        out.append({"label": label, "campaign": config["datasets"][dataset]["campaign"],
                    "runs": [{"run": run, "raw_dir": raw_run_dir(config, dataset, scenario, run),
                              "tables": f"data/processed/{dataset}/{scenario}/tables/{shard_of[run]}/{run}"}
                             for run in runs]})
    return out


def study_reference_inputs(w):
    """The table folders and raw files the references read (so they run after ingest)."""
    files = []
    for scenario in study_references(w):
        dataset, name = scenario["label"].split("/", 1)
        for run in scenario["runs"]:
            files += [str(Path(run["tables"]).parent)] + raw_files(dataset, name, [run["run"]])
    return files


def sweep_campaign(spec, key):
    """[campaign file] of an experiment's sweep scenario (spec[key]: scenario, runs); [] when off."""
    sweep = (spec or {}).get(key) or {}
    return [campaign_of_label(sweep["scenario"])] if sweep.get("runs") else []


def sweep_tables(spec, key):
    """The workflow's table folders of an experiment's sweep scenario when the workflow simulates
    it (a sweep level without changes reuses those runs); [] when off, real logs or a scenario
    the dataset does not list (the sweep then simulates all its runs itself)."""
    sweep = (spec or {}).get(key) or {}
    if not sweep.get("runs"):
        return []
    dataset, scenario = sweep["scenario"].split("/", 1)
    spec = config["datasets"][dataset]
    return tables_of(dataset, scenario) if spec["source"] == "simulate" and scenario in spec["scenarios"] else []


def campaign_of_label(label):
    """Campaign file of a dataset/scenario label."""
    dataset, _ = label.split("/", 1)
    return config["datasets"][dataset]["campaign"]


def first_run_tables(dataset):
    """Table folder of the dataset's first run, ordered by scenario, shard and run name: the
    run whose true path its floor plan shows."""
    scenario, shard, run = min((scenario, shard, run) for scenario in config["datasets"][dataset]["scenarios"]
                               for shard, runs in shards_of(config, dataset, scenario).items() for run in runs)
    return f"data/processed/{dataset}/{scenario}/tables/{shard}/{run}"
