# Helpers shared by the rules: which datasets, scenarios and runs exist, and where.

from wsnloc.workflow import dataset_runs, raw_run_dir, scenario_pairs, simulated_runs

ENV = "../envs/wsnloc.yaml"
SIM_FILES = ["uwb.log", "zigbee.log", "imu.log", "truth.log", "meta.yaml"]
RAW_FILES = {"newcom": ["uwb.log", "zigbee.log", "imu.log", "truth.log"]}
SIMULATED = [name for name, d in config["datasets"].items() if d["source"] == "simulate"]
PAIRS = scenario_pairs(config)


wildcard_constraints:
    dataset="|".join(config["datasets"]) or "^$",
    scenario=r"[A-Za-z0-9_-]+",


def raw_inputs(wildcards):
    """Raw log files of every run of one scenario (simulated or real)."""
    dataset = config["datasets"][wildcards.dataset]
    names = RAW_FILES[dataset["format"]]
    return [
        f"{raw_run_dir(config, wildcards.dataset, wildcards.scenario, run)}/{name}"
        for run in dataset_runs(config, wildcards.dataset, wildcards.scenario)
        for name in names
    ]


def campaign_file(wildcards):
    return config["datasets"][wildcards.dataset]["campaign"]


def experiment_pairs(spec, key="scenarios"):
    """(dataset, scenario) pairs an experiment runs on; none when it is not configured."""
    return [tuple(label.split("/", 1)) for label in spec[key]] if spec else []


def scenario_outputs(pattern):
    """Expand a per-scenario path pattern over every (dataset, scenario) pair."""
    return [pattern.format(dataset=d, scenario=s) for d, s in PAIRS]
