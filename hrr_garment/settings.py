"""Settings dataclasses filled from YAML/JSON mappings: unknown keys are an error, not ignored."""

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
