"""Workflow helpers used by the Snakefile: datasets, scenarios, runs and their paths.

Simulated datasets write to data/raw/<dataset>/<scenario>/run-NN; datasets with
`source: logs` are read from <raw_dir>/<scenario>/<run>/ and their runs are the
sub-directories found there, or, for a dataset converted by the workflow (`convert:
{dataset, source}`), the runs its converter writes from the source (io.convert.run_names).
"""

from __future__ import annotations

from pathlib import Path

from wsnloc.errors import ConfigError

SIMULATED_ROOT = "data/raw"


def run_name(index: int, total: int) -> str:
    return f"run-{index:0{max(2, len(str(total)))}d}"


def simulated_runs(config: dict) -> list[str]:
    return [run_name(i, config["runs"]) for i in range(1, config["runs"] + 1)]


def raw_root(config: dict, dataset: str) -> str:
    spec = config["datasets"][dataset]
    return f"{SIMULATED_ROOT}/{dataset}" if spec["source"] == "simulate" else spec["raw_dir"].rstrip("/")


def dataset_runs(config: dict, dataset: str, scenario: str) -> list[str]:
    """Run names of one scenario; for real logs, the run directories present on disk."""
    spec = config["datasets"][dataset]
    if spec["source"] == "simulate":
        return simulated_runs(config)
    if spec.get("convert"):        # written by the workflow's conversion rule: known from the source
        from wsnloc.io.convert import run_names

        runs = run_names(spec["convert"]["dataset"], spec["convert"]["source"]).get(scenario, [])
        if not runs:
            raise ConfigError(f"config key 'datasets.{dataset}.scenarios': {scenario!r} has no runs in "
                              f"{spec['convert']['source']}")
        return runs
    folder = Path(raw_root(config, dataset)) / scenario
    runs = sorted(p.name for p in folder.iterdir() if p.is_dir()) if folder.is_dir() else []
    if not runs:
        raise ConfigError(f"config key 'datasets.{dataset}.raw_dir': no run directories in {folder}")
    return runs


def raw_run_dir(config: dict, dataset: str, scenario: str, run: str) -> str:
    return f"{raw_root(config, dataset)}/{scenario}/{run}"


def shards_of(config: dict, dataset: str, scenario: str) -> dict[str, list[str]]:
    """The scenario's runs split into `config['shards']` contiguous groups (no empty group).

    Each group is one ingest (+ IMU resampling) job, and shard k of every simulated scenario of
    a format one simulation job: 1 shard on a laptop, many on a cluster. Shard names are
    shard-1, shard-2, ...
    """
    return split_runs(dataset_runs(config, dataset, scenario), config.get("shards", 1))


def simulated_shards(config: dict) -> dict[str, list[str]]:
    """Shards of a simulated scenario (all simulated scenarios have the same runs)."""
    return split_runs(simulated_runs(config), config.get("shards", 1))


def split_runs(runs: list[str], shards: int) -> dict[str, list[str]]:
    """Contiguous groups shard-1 .. shard-N of about equal size, never empty."""
    count = max(1, min(shards, len(runs)))
    bounds = [round(i * len(runs) / count) for i in range(count + 1)]
    return {f"shard-{k + 1}": runs[bounds[k]:bounds[k + 1]] for k in range(count)}


def processed_dirs(config: dict, dataset: str, scenario: str, stage: str) -> list[str]:
    """Per-shard folders of one stage ('tables' or 'imu_5hz') of a scenario."""
    return [f"data/processed/{dataset}/{scenario}/{stage}/{shard}" for shard in shards_of(config, dataset, scenario)]


def scenario_pairs(config: dict) -> list[tuple[str, str]]:
    return [(d, s) for d, spec in config["datasets"].items() for s in spec["scenarios"]]


def each_scenario(sources: dict, outputs, names: tuple[str, ...]):
    """(label, campaign, {name: path}) for each scenario of a job over several scenarios, in
    order: `sources` is the rule's params built by scenario_sources (common.smk), `outputs`
    the rule's output with one list per name (scenario_files), scenario i's files at index i."""
    from wsnloc.campaign import Campaign    # here: the Snakefile imports this module before any job

    campaigns = {path: Campaign.load(path) for path in set(sources["campaign_of"].values())}
    for i, label in enumerate(sources["labels"]):
        yield label, campaigns[sources["campaign_of"][label]], {name: getattr(outputs, name)[i] for name in names}


def read_scenario_files(outputs, labels: list[str]) -> dict[str, dict]:
    """The per-scenario files a paper's job wrote (the rule's outputs, one list per name,
    scenario i's file at index i), read back as {name: {label: frame}}: `metrics` and
    `sensitivity` CSV as written (6 significant digits, so the tables are computed from the
    numbers on disk), `estimates` with io.tables.read and, where the paper writes it, `quality`."""
    import pandas as pd

    from wsnloc.io import tables

    readers = {"metrics": pd.read_csv, "sensitivity": pd.read_csv, "estimates": tables.read,
               "quality": pd.read_parquet}
    return {name: dict(zip(labels, map(read, getattr(outputs, name))))
            for name, read in readers.items() if name in outputs.keys()}


def start_job(log_path: str, name: str):
    """Start a workflow script's job, after its imports: freeze the objects created so far and
    return a logger writing to the rule's log file (Snakemake's `log:`).

    gc.freeze moves every object alive now (the imported modules' functions, classes and
    tables: a few hundred thousand in a job with pandas) out of the cyclic garbage collector's
    generations, so its full collections no longer scan them again and again (measured about
    2 s of CPU less over the default build's jobs, when each job was a fresh interpreter). The
    job server freezes what it imported before it forks a job; this freezes what the job's own
    imports added. Those objects live until the job ends anyway.
    """
    import gc
    import logging

    gc.freeze()
    Path(log_path).parent.mkdir(parents=True, exist_ok=True)
    logger = logging.getLogger(name)
    logger.setLevel(logging.INFO)
    handler = logging.FileHandler(log_path, mode="w")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    logger.addHandler(handler)
    return logger


def compile_bytecode(package_dir: str | Path = Path(__file__).parent) -> None:
    """Write the bytecode (__pycache__) of the package's modules once, before the jobs start.

    Python writes it on a module's first import unless PYTHONDONTWRITEBYTECODE is set, as in
    many containers; then every job would compile the 60-100 wsnloc modules it imports from
    source, about 0.1 s of CPU per job. compileall leaves up-to-date files alone (it compares
    the source's modification time and size); where the package cannot be written to, the
    jobs compile on import as before (quiet: a cache, not a result).
    """
    import compileall

    compileall.compile_dir(str(package_dir), quiet=2)


def without_missing_sources(config: dict) -> list[str]:
    """Drop the datasets whose `convert.source` folder is absent, and their scenarios from the
    studies (a study left without scenarios is dropped); returns one message per dataset dropped."""
    messages = []
    for name, spec in list(config.get("datasets", {}).items()):
        source = (spec or {}).get("convert", {}).get("source")
        if source and not Path(source).is_dir():
            del config["datasets"][name]
            messages.append(f"dataset {name!r} skipped: its source {source!r} is not there (convert.source)")
    for study, spec in list((config.get("studies") or {}).items()):
        kept = [label for label in spec.get("scenarios", []) if label.split("/", 1)[0] in config["datasets"]]
        if not kept:
            del config["studies"][study]
        else:
            spec["scenarios"] = kept
            spec["overrides"] = {k: v for k, v in (spec.get("overrides") or {}).items()
                                 if k.split("/", 1)[0] in config["datasets"]}
    return messages
