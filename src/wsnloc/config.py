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

from wsnloc.errors import ConfigError, did_you_mean

# libyaml's parser when PyYAML was built with it (same safe schema, ~10x faster than the pure
# Python one: every job reads its campaign file).
_SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def parse_yaml(text: str) -> Any:
    """yaml.safe_load with libyaml's parser when available (raises yaml.YAMLError)."""
    return yaml.load(text, Loader=_SafeLoader)


def read_yaml(path: str | Path) -> Any:
    """Parse a YAML file; a syntax error becomes a ConfigError naming the file and line."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror})") from exc
    try:
        return parse_yaml(text)
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
        close = "".join(did_you_mean(k, allowed) for k in unknown) if len(unknown) == 1 else ""
        hint = f" (allowed here: {', '.join(sorted(allowed))})" if allowed else ""
        return f"config key {keys}: unknown key{close}{hint}"
    if error.validator == "required":
        missing = error.message.split("'")[1] if "'" in error.message else error.message
        prefix = f"{where}." if error.absolute_path else ""
        return f"config key '{prefix}{missing}': required but missing"
    if error.validator == "enum" and isinstance(error.instance, str):
        return f"config key '{where}': {error.message}{did_you_mean(error.instance, error.validator_value)}"
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


def config_hash(config: dict) -> str:
    """SHA-256 of the effective configuration (canonical JSON), for provenance."""
    canonical = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()
