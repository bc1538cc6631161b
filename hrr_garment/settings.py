"""Settings dataclasses filled from YAML/JSON mappings (unknown keys are an error, not ignored), and
layered mappings merged."""

from __future__ import annotations

from typing import TypeVar

from .errors import HRRError

T = TypeVar("T")


class SettingsError(HRRError, ValueError):
    """A settings mapping with keys the dataclass does not have."""


def from_settings(cls: type[T], values: dict, what: str) -> T:
    """``cls(**values)`` after checking every key is one of the dataclass's fields."""
    unknown = set(values) - set(cls.__dataclass_fields__)  # type: ignore[attr-defined]
    if unknown:
        raise SettingsError(f"unknown {what} settings: {', '.join(sorted(unknown))}")
    return cls(**values)


def deep_merge(base: dict, override: dict) -> dict:
    """``override``'s values over ``base``'s, mappings merged key by key at every depth (a config
    file over the defaults: it names only what it changes)."""
    out = dict(base)
    for key, value in (override or {}).items():
        out[key] = deep_merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out
