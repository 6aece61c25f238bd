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


def simulated_runs(config: dict, dataset: str | None = None, scenario: str | None = None) -> list[str]:
    """Run names of a simulated scenario: `datasets.<dataset>.scenario_runs.<scenario>` runs where
    set (a scenario only a few cells read), else the top-level `runs`; without a scenario, `runs`."""
    spec = config["datasets"].get(dataset) or {} if dataset else {}
    count = (spec.get("scenario_runs") or {}).get(scenario, config["runs"])
    return [run_name(i, count) for i in range(1, count + 1)]


def raw_root(config: dict, dataset: str) -> str:
    spec = config["datasets"][dataset]
    return f"{SIMULATED_ROOT}/{dataset}" if spec["source"] == "simulate" else spec["raw_dir"].rstrip("/")


def dataset_runs(config: dict, dataset: str, scenario: str) -> list[str]:
    """Run names of one scenario; for real logs, the run directories present on disk."""
    spec = config["datasets"][dataset]
    if spec["source"] == "simulate":
        return simulated_runs(config, dataset, scenario)
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


def simulated_shards(config: dict) -> list[str]:
    """Names of the shards of the simulated scenarios (shard-1 .. shard-N, as many as the scenario
    with the most runs has; shard k of a scenario with fewer runs may be absent from shards_of)."""
    counts = [config["runs"]] + [n for spec in config["datasets"].values() if spec["source"] == "simulate"
                                 for n in (spec.get("scenario_runs") or {}).values()]
    return [f"shard-{k}" for k in range(1, min(config.get("shards", 1), max(counts)) + 1)]


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


def start_job(smk) -> "logging.Logger":
    """Start a workflow script's job (Snakemake `script:`); its first statement.

    The rule's log file (Snakemake `log:`, smk.log[0]) receives the script's log records, its
    standard error (warnings) and, if it fails, the traceback; the terminal gets one line: the
    rule, the error's message (an error of this package names its file, line or config key)
    and where the traceback is. Returns the logger of the job.

    Garbage collector: each job imports pandas, pyarrow (often matplotlib and scipy), a few
    hundred thousand long-lived objects that every full collection, and the last one at exit,
    scans again. After each full collection the survivors are frozen (gc.freeze: never
    scanned again; a job lives seconds to minutes, and what is freed by reference counting is
    still freed), and at exit everything is: measured about 0.5 s of CPU less per job with
    pandas and matplotlib loaded.
    """
    import atexit
    import gc
    import logging
    import sys
    import traceback

    from wsnloc.errors import WsnlocError

    path = Path(smk.log[0])
    path.parent.mkdir(parents=True, exist_ok=True)
    stream = open(path, "w", buffering=1, encoding="utf-8")
    terminal, sys.stderr = sys.stderr, stream

    def report(kind, error, tb):
        traceback.print_exception(kind, error, tb, file=stream)
        stream.flush()
        message = str(error) if isinstance(error, WsnlocError) else f"{kind.__name__}: {error}"
        terminal.write(f"error in rule {smk.rule}: {message} (traceback: {path})\n")
        terminal.flush()

    sys.excepthook = report
    gc.callbacks.append(lambda phase, info: gc.freeze() if phase == "stop" and info["generation"] == 2 else None)
    atexit.register(gc.freeze)
    logger = logging.getLogger(smk.rule)
    logger.setLevel(logging.INFO)
    handler = logging.StreamHandler(stream)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    logger.addHandler(handler)
    return logger


REPORT = "reports/index.html"
RESULTS = "reports/results.csv"


def finished_build() -> str:
    """The last lines of a successful build (the Snakefile's onsuccess): where the report and
    the results table are, with their size (the report: its pages and PNG figures under
    `pages/` beside the index, and the bytes of all of them)."""
    lines = []
    for label, path in (("report", REPORT), ("results", RESULTS)):
        file = Path(path)
        if file.exists():
            if label == "report":
                pages = list((file.parent / "pages").glob("*.html"))
                figures = list((file.parent / "pages").glob("**/*.png"))
                size = sum(f.stat().st_size for f in [file, *pages, *figures])
                detail = f"{len(pages) + 1} pages, {len(figures)} figures, {size / 1e6:.1f} MB"
            else:
                detail = f"{sum(1 for _ in file.open()) - 1} rows"
            lines.append(f"{label + ':':9}{path} ({detail})")
    return "\n".join(lines) if lines else "done (the report was not among the targets)"


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
