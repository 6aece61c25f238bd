# Helpers shared by the rules: which datasets, scenarios and runs exist, and where.
from pathlib import Path


from wsnloc.workflow import dataset_runs, raw_run_dir, scenario_pairs, simulated_runs

ENV = "../envs/wsnloc.yaml"
RAW_FILES = {"newcom": ["uwb.log", "zigbee.log", "imu.log", "truth.log"],
             "cricket": ["listener.log", "imu.log", "truth.log"]}
SIMULATED = [name for name, d in config["datasets"].items() if d["source"] == "simulate"]
PAIRS = scenario_pairs(config)


wildcard_constraints:
    dataset="|".join(config["datasets"]) or "^$",
    scenario=r"[A-Za-z0-9_-]+",


def raw_inputs(wildcards):
    """Raw files of every run of one scenario (simulated or real; generic: what is there)."""
    dataset = config["datasets"][wildcards.dataset]
    files = []
    for run in dataset_runs(config, wildcards.dataset, wildcards.scenario):
        run_dir = raw_run_dir(config, wildcards.dataset, wildcards.scenario, run)
        if dataset["format"] == "generic":
            files += sorted(str(p) for p in Path(run_dir).iterdir() if p.suffix in (".csv", ".parquet"))
        else:
            files += [f"{run_dir}/{name}" for name in RAW_FILES[dataset["format"]]]
    return files


def campaign_file(wildcards):
    return config["datasets"][wildcards.dataset]["campaign"]


def simulated_of(fmt):
    """Regex of the simulated datasets of one format (never matches when there are none)."""
    names = [n for n in SIMULATED if config["datasets"][n]["format"] == fmt]
    return "|".join(names) or "(?!x)x"


def experiment_pairs(spec, key="scenarios"):
    """(dataset, scenario) pairs an experiment runs on; none when it is not configured."""
    return [tuple(label.split("/", 1)) for label in spec[key]] if spec else []


def scenario_outputs(pattern):
    """Expand a per-scenario path pattern over every (dataset, scenario) pair."""
    return [pattern.format(dataset=d, scenario=s) for d, s in PAIRS]
