"""The workflow configuration checked before any job runs (Snakefile, `wsnloc validate-config`).

The schema (wsnloc.config.validate, filling defaults) first, then what the schema cannot
know: campaign files and their scenarios, real-log directories, the scenarios and anchor
subsets the experiments name, and the studies. Every error names the config key.
"""

from __future__ import annotations

from pathlib import Path

from wsnloc.campaign import Campaign
from wsnloc.config import read_yaml, validate
from wsnloc.errors import ConfigError, did_you_mean
from wsnloc.studies import validate_studies

DEFAULT_KIND = {"simulate": "simulated", "logs": "measured"}   # datasets.<name>.kind by source (schema)


def dataset_kind(spec: dict) -> str:
    """What a dataset's data are: its `kind`, else DEFAULT_KIND of its source."""
    return spec.get("kind") or DEFAULT_KIND[spec["source"]]


SUBSET_KEYS = {   # where each paper names anchor subsets (joined by '+')
    "paper_a": ("rows[].anchors",),
    "paper_b": ("parameters.anchors",),
    "paper_c": ("table_1_subset", "table_2_subsets[]"),
    "paper_d": ("parameters.anchors",),
}


def _values_at(node, path: str, prefix: str):
    """(dotted key, value) of every value at `path` ('a.b', 'rows[].uwb') under `node`."""
    head, _, rest = path.partition(".")
    name, every = head.removesuffix("[]"), head.endswith("[]")
    if not isinstance(node, dict) or name not in node:
        return
    children = [(f"{prefix}.{name}[{i}]", item) for i, item in enumerate(node[name])] if every \
        else [(f"{prefix}.{name}", node[name])]
    for key, child in children:
        if rest:
            yield from _values_at(child, rest, key)
        else:
            yield key, child


def _check_datasets(config: dict) -> dict:
    """Campaign files load, simulated scenarios exist in them, real logs are on disk; each
    dataset's `kind` defaults from its source (simulate: simulated, logs: measured).

    Returns the loaded campaign of each dataset.
    """
    campaigns = {}
    for name, dataset in config["datasets"].items():
        if not Path(dataset["campaign"]).is_file():
            raise ConfigError(f"config key 'datasets.{name}.campaign': no such file {dataset['campaign']!r}")
        campaigns[name] = campaign = Campaign.load(dataset["campaign"])
        kind = dataset.setdefault("kind", dataset_kind(dataset))
        if (kind == "simulated") != (dataset["source"] == "simulate"):
            raise ConfigError(f"config key 'datasets.{name}.kind': {kind!r} does not fit source "
                              f"{dataset['source']!r} (simulate: simulated; logs: measured or synthetic)")
        if dataset["source"] == "simulate":
            for scenario in dataset.get("scenario_runs") or {}:
                if scenario not in dataset["scenarios"]:
                    raise ConfigError(f"config key 'datasets.{name}.scenario_runs.{scenario}': not one of the "
                                      f"dataset's scenarios{did_you_mean(scenario, dataset['scenarios'])} "
                                      f"({', '.join(dataset['scenarios'])})")
            defined = campaign.spec.get("scenarios", {})
            for scenario in dataset["scenarios"]:
                if scenario not in defined:
                    raise ConfigError(f"config key 'datasets.{name}.scenarios': {scenario!r} is not a scenario of "
                                      f"{dataset['campaign']}{did_you_mean(scenario, defined)} "
                                      f"(defined there: {', '.join(defined) or 'none'})")
            continue
        if not dataset.get("raw_dir"):
            raise ConfigError(f"config key 'datasets.{name}.raw_dir': required when source is 'logs'")
        if not dataset.get("convert") and not Path(dataset["raw_dir"]).is_dir():   # convert: the workflow writes raw_dir
            raise ConfigError(f"config key 'datasets.{name}.raw_dir': no such directory {dataset['raw_dir']!r}")
        if dataset.get("scenario_runs"):
            raise ConfigError(f"config key 'datasets.{name}.scenario_runs': only a simulated dataset (source "
                              f"simulate) sets its runs; real logs have the runs found on disk")
        if dataset.get("convert"):
            continue
        for scenario in dataset["scenarios"]:
            folder = Path(dataset["raw_dir"]) / scenario
            if not folder.is_dir() or not any(p.is_dir() for p in folder.iterdir()):
                raise ConfigError(f"config key 'datasets.{name}.scenarios': {scenario!r} has no run directories "
                                  f"in {folder}")
    return campaigns


def _check_experiments(config: dict, campaigns: dict) -> None:
    """Experiments run on declared scenarios, declare their cells as registry estimators
    (experiments.cells.check), and name subsets their campaigns define."""
    from wsnloc.experiments import cells

    declared = {f"{d}/{s}" for d, spec in config["datasets"].items() for s in spec["scenarios"]}
    for experiment, spec in config.get("experiments", {}).items():
        used = []
        for key in ("scenarios", "simulation_scenarios"):
            for label in spec.get(key, []):
                if label not in declared:
                    raise ConfigError(f"config key 'experiments.{experiment}.{key}': {label!r} is not a declared "
                                      f"dataset/scenario{did_you_mean(label, declared)} "
                                      f"(declared: {', '.join(sorted(declared))})")
                used.append(label.split("/")[0])
        if "table_2_scenario" in spec and spec["table_2_scenario"] not in spec["scenarios"]:
            raise ConfigError(f"config key 'experiments.{experiment}.table_2_scenario': "
                              f"{spec['table_2_scenario']!r} is not one of its scenarios "
                              f"({', '.join(spec['scenarios'])})")
        for path in SUBSET_KEYS.get(experiment, ()):
            for key, expression in _values_at(spec, path, f"experiments.{experiment}"):
                for subset, dataset in ((s, d) for s in expression.split("+") for d in dict.fromkeys(used)):
                    defined = campaigns[dataset].spec.get("subsets", {})
                    if subset not in defined:
                        raise ConfigError(f"config key '{key}': {subset!r} is not an anchor subset of "
                                          f"{config['datasets'][dataset]['campaign']} (dataset {dataset}; "
                                          f"defined there: {', '.join(defined) or 'none'})")
        cells.check(spec, experiment)


def validate_config(config: dict, schema_path: str | Path) -> dict:
    """Validate the workflow configuration against the schema, then everything else that
    can be known before a job runs: campaign files and their scenarios, real-log
    directories, the scenarios experiments run on and the anchor subsets they name, and
    the studies' estimators, parameters, overrides and subsets (wsnloc.studies)."""
    validate(config, read_yaml(schema_path), source="config")
    campaigns = _check_datasets(config)
    _check_experiments(config, campaigns)
    _check_ranging_validation(config, campaigns)
    validate_studies(config)
    return config


def _check_ranging_validation(config: dict, campaigns: dict) -> None:
    """The ranging validation shows declared scenarios; the first one's campaign has the UWB
    receiver (radio.uwb) that reads the channel models alone."""
    declared = {f"{d}/{s}" for d, spec in config["datasets"].items() for s in spec["scenarios"]}
    labels = (config.get("ranging_validation") or {}).get("scenarios", [])
    for label in labels:
        if label not in declared:
            raise ConfigError(f"config key 'ranging_validation.scenarios': {label!r} is not a declared "
                              f"dataset/scenario{did_you_mean(label, declared)} (declared: {', '.join(sorted(declared))})")
    if labels and "uwb" not in campaigns[labels[0].split("/")[0]].spec.get("radio", {}):
        raise ConfigError(f"config key 'ranging_validation.scenarios': the campaign of {labels[0]!r} has no radio.uwb "
                          f"receiver to read the IEEE 802.15.4a channel models")
