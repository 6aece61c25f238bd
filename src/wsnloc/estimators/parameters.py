"""Estimator parameters: name, default, unit and meaning, and their checked resolution.

Every estimator of the registry declares its parameters with a default and a unit; a
study or the command line overrides some of them. Unknown names and values of the wrong
kind are refused with a message naming the key (`where`, e.g. the config path) and, for a
misspelled name or choice, the closest known ones (errors.did_you_mean).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from wsnloc.errors import ConfigError, did_you_mean


@dataclass(frozen=True)
class Param:
    """One parameter: `kind` is float, int, bool or str; `choices` restricts a str."""

    name: str
    default: Any
    unit: str
    doc: str
    kind: type = float
    choices: tuple[str, ...] | None = None
    minimum: float | None = None

    def check(self, value: Any, where: str) -> Any:
        """The value converted to `kind`; ConfigError naming `where` when it does not fit."""
        if value is None and self.default is None:
            return None
        if self.kind is bool:
            if isinstance(value, bool):
                return value
            if isinstance(value, str) and value.lower() in ("true", "false", "yes", "no", "1", "0"):
                return value.lower() in ("true", "yes", "1")
            raise ConfigError(f"config key '{where}': expected true or false, got {value!r}")
        if self.kind is str:
            value = str(value)
            if self.choices and value not in self.choices:
                raise ConfigError(f"config key '{where}': {value!r} is not one of {', '.join(self.choices)}"
                                  f"{did_you_mean(value, self.choices)}")
            return value
        try:
            if isinstance(value, bool):
                raise ValueError
            number = self.kind(value)
            if self.kind is int and float(value) != number:
                raise ValueError
        except (TypeError, ValueError):
            raise ConfigError(f"config key '{where}': expected a {self.kind.__name__}"
                              f"{f' in {self.unit}' if self.unit else ''}, got {value!r}") from None
        if self.minimum is not None and number < self.minimum:
            raise ConfigError(f"config key '{where}': {number} is less than the minimum of {self.minimum}")
        return number

    def describe(self) -> dict:
        out = {"name": self.name, "default": self.default, "unit": self.unit, "doc": self.doc,
               "type": self.kind.__name__}
        if self.choices:
            out["choices"] = list(self.choices)
        return out


def resolve(params: tuple[Param, ...], overrides: dict, where: str) -> dict:
    """Defaults of `params` with `overrides` applied; refuses names the estimator lacks."""
    known = {p.name: p for p in params}
    unknown = sorted(set(overrides) - set(known))
    if unknown:
        raise ConfigError(f"config key '{where}.{unknown[0]}': unknown parameter"
                          f"{did_you_mean(unknown[0], known)} (this estimator has: {', '.join(sorted(known))})")
    return {name: p.check(overrides[name], f"{where}.{name}") if name in overrides else p.default
            for name, p in known.items()}


def parse_assignment(text: str) -> tuple[str, str]:
    """`key=value` from the command line's --set."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {text!r}: expected key=value")
    return key.strip(), value.strip()
