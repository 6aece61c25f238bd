"""Load and validate YAML configuration against a JSON schema, filling defaults.

Used by the Snakefile before any job runs and by the command line. Every error message
names the key (dotted path) that is wrong, so a user can find it in config.yaml.
"""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from wsnloc.errors import ConfigError


def read_yaml(path: str | Path) -> Any:
    """Parse a YAML file; a syntax error becomes a ConfigError naming the file and line."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror})") from exc
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else str(path)
        raise ConfigError(f"{where}: invalid YAML ({getattr(exc, 'problem', exc)})") from exc


def _with_defaults(validator_class):
    """Extend a jsonschema validator so that `default` values are written into the instance."""
    validate_properties = validator_class.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, schema):
        if isinstance(instance, dict):
            for name, subschema in properties.items():
                if "default" in subschema and name not in instance:
                    instance[name] = copy.deepcopy(subschema["default"])
        yield from validate_properties(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_class, {"properties": set_defaults})


_DefaultFillingValidator = _with_defaults(jsonschema.Draft202012Validator)


def _key_path(error: jsonschema.ValidationError) -> str:
    return ".".join(str(part) for part in error.absolute_path) or "<top level>"


def _describe(error: jsonschema.ValidationError) -> str:
    """One readable sentence for a schema violation, starting with the key it concerns."""
    where = _key_path(error)
    if error.validator == "additionalProperties" and isinstance(error.instance, dict):
        allowed = set(error.schema.get("properties", {}))
        unknown = sorted(k for k in error.instance if k not in allowed)
        prefix = f"{where}." if error.absolute_path else ""
        keys = ", ".join(f"'{prefix}{k}'" for k in unknown)
        hint = f" (allowed here: {', '.join(sorted(allowed))})" if allowed else ""
        return f"config key {keys}: unknown key{hint}"
    if error.validator == "required":
        missing = error.message.split("'")[1] if "'" in error.message else error.message
        prefix = f"{where}." if error.absolute_path else ""
        return f"config key '{prefix}{missing}': required but missing"
    return f"config key '{where}': {error.message}"


def validate(instance: dict, schema: dict, source: str = "config") -> dict:
    """Validate `instance` in place against `schema`, fill defaults, and return it.

    Raises ConfigError listing every violation, each naming its key.
    """
    if not isinstance(instance, dict):
        raise ConfigError(f"{source}: expected a mapping at the top level, got {type(instance).__name__}")
    validator = _DefaultFillingValidator(schema)
    errors = sorted(validator.iter_errors(instance), key=lambda e: list(map(str, e.absolute_path)))
    if errors:
        lines = "\n  ".join(_describe(e) for e in errors)
        raise ConfigError(f"{source} is invalid:\n  {lines}")
    return instance


# Where each experiment names anchor subsets of its datasets' campaigns ("[]": every item).
SUBSET_KEYS = {
    "paper_a": ("rows[].uwb", "rows[].zigbee"),
    "paper_b": ("uwb_subset",),
    "paper_c": ("table_1_subset", "table_2_subsets[]"),
    "paper_d": ("subsets.uwb", "subsets.narrowband"),
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
    """Campaign files load, simulated scenarios exist in them, real logs are on disk.

    Returns the loaded campaign of each dataset.
    """
    from wsnloc.campaign import Campaign       # campaign.py imports this module

    campaigns = {}
    for name, dataset in config["datasets"].items():
        if not Path(dataset["campaign"]).is_file():
            raise ConfigError(f"config key 'datasets.{name}.campaign': no such file {dataset['campaign']!r}")
        campaigns[name] = campaign = Campaign.load(dataset["campaign"])
        if dataset["source"] == "simulate":
            defined = campaign.spec.get("scenarios", {})
            for scenario in dataset["scenarios"]:
                if scenario not in defined:
                    raise ConfigError(f"config key 'datasets.{name}.scenarios': {scenario!r} is not a scenario of "
                                      f"{dataset['campaign']} (defined there: {', '.join(defined) or 'none'})")
            continue
        if not dataset.get("raw_dir"):
            raise ConfigError(f"config key 'datasets.{name}.raw_dir': required when source is 'logs'")
        if not Path(dataset["raw_dir"]).is_dir():
            raise ConfigError(f"config key 'datasets.{name}.raw_dir': no such directory {dataset['raw_dir']!r}")
        for scenario in dataset["scenarios"]:
            folder = Path(dataset["raw_dir"]) / scenario
            if not folder.is_dir() or not any(p.is_dir() for p in folder.iterdir()):
                raise ConfigError(f"config key 'datasets.{name}.scenarios': {scenario!r} has no run directories "
                                  f"in {folder}")
    return campaigns


def _check_experiments(config: dict, campaigns: dict) -> None:
    """Experiments run on declared scenarios, and name subsets their campaigns define."""
    declared = {f"{d}/{s}" for d, spec in config["datasets"].items() for s in spec["scenarios"]}
    for experiment, spec in config.get("experiments", {}).items():
        used = []
        for key in ("scenarios", "simulation_scenarios"):
            for label in spec.get(key, []):
                if label not in declared:
                    raise ConfigError(f"config key 'experiments.{experiment}.{key}': {label!r} is not a declared "
                                      f"dataset/scenario (declared: {', '.join(sorted(declared))})")
                used.append(label.split("/")[0])
        if "table_2_scenario" in spec and spec["table_2_scenario"] not in spec["scenarios"]:
            raise ConfigError(f"config key 'experiments.{experiment}.table_2_scenario': "
                              f"{spec['table_2_scenario']!r} is not one of its scenarios "
                              f"({', '.join(spec['scenarios'])})")
        for path in SUBSET_KEYS.get(experiment, ()):
            for key, subset in _values_at(spec, path, f"experiments.{experiment}"):
                for dataset in dict.fromkeys(used):
                    defined = campaigns[dataset].spec.get("subsets", {})
                    if subset not in defined:
                        raise ConfigError(f"config key '{key}': {subset!r} is not an anchor subset of "
                                          f"{config['datasets'][dataset]['campaign']} (dataset {dataset}; "
                                          f"defined there: {', '.join(defined) or 'none'})")


def validate_config(config: dict, schema_path: str | Path) -> dict:
    """Validate the workflow configuration against the schema, then everything else that
    can be known before a job runs: campaign files and their scenarios, real-log
    directories, the scenarios experiments run on and the anchor subsets they name."""
    validate(config, read_yaml(schema_path), source="config")
    campaigns = _check_datasets(config)
    _check_experiments(config, campaigns)
    return config


def config_hash(config: dict) -> str:
    """SHA-256 of the effective configuration (canonical JSON), for provenance."""
    canonical = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()
