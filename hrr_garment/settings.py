"""Settings dataclasses filled from YAML/JSON mappings (unknown keys are an error, not ignored), and
layered mappings merged."""

from __future__ import annotations

import math
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
        out[key] = (
            deep_merge(out[key], value)
            if isinstance(value, dict) and isinstance(out.get(key), dict)
            else value
        )
    return out


def require_number(
    what: str,
    name: str,
    value,
    *,
    low: float | None = None,
    high: float | None = None,
    whole: bool = False,
    above: bool = False,
) -> None:
    """Refuse a setting that is not a finite number (a whole one with ``whole``) from ``low``
    (exclusive with ``above``) to ``high``: a hand-edited file's -5 window or "x" scale fails here,
    named, instead of deep in the model."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    ok = ok and (not whole or float(value).is_integer())
    ok = ok and (low is None or (value > low if above else value >= low)) and (high is None or value <= high)
    if not ok:
        bounds = (
            [f"above {low:g}" if above else (f"from {low:g}" if high is not None else f"at least {low:g}")]
            if low is not None
            else []
        )
        bounds += (
            [f"{'and at most' if above else 'to'} {high:g}" if bounds else f"at most {high:g}"]
            if high is not None
            else []
        )
        span = " ".join(bounds)
        raise SettingsError(
            f"{what}: {name} must be a {'whole ' if whole else ''}number {span}, got {value!r}"
        )
