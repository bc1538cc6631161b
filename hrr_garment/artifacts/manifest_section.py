"""The building block of the typed manifest (:mod:`.manifest_entries`, :mod:`.typed_manifest`): a
frozen dataclass per section of bundle.json that reads its JSON object, checked, and writes back the
same JSON.

Round trip: ``Section.parse(d).to_dict() == d`` with the keys in ``d``'s order, so that a manifest
read and written again (a calibration recorded, a part added) changes only what the writer changed,
and its manifest hash (:func:`~.manifest.manifest_hash`, over the JSON content) is what it was.
Keys a section does not type (a training report's numbers, a note, a field from a newer minor
writer) are kept in ``extra``, read-only, and written back as they were: bundle.json has always
tolerated them, and they are part of what its hashes cover. A typed field that is None is absent
from the JSON, except the fields of ``NULLABLE`` that were read as ``null`` (``auto.residual_free_mm``,
``bodies.default``...), which are written back as ``null``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import Any, ClassVar, Self

from ..io_utils import strict_json

#: what the round trip leaves out of a section's JSON: the bookkeeping fields
_BOOKKEEPING = ("extra", "order")


class ManifestFieldError(ValueError):
    """A field of bundle.json that is missing or of the wrong kind: the message names it (the
    manifest's reader turns it into a :class:`~.manifest.BundleError` naming the folder)."""


def frozen(value: Any) -> Any:
    """A JSON value read-only: objects as read-only mappings, lists as tuples, all the way down."""
    if isinstance(value, Mapping):
        return MappingProxyType({k: frozen(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(frozen(v) for v in value)
    return value


def as_json(value: Any) -> Any:
    """A value computed in memory as bundle.json holds it: through
    :func:`~hrr_garment.io_utils.strict_json`, which writes non-finite numbers as null."""
    return json.loads(strict_json(value))


def thawed(value: Any) -> Any:
    """A (frozen) value as JSON: sections and mappings as dicts, tuples as lists, all the way down."""
    if isinstance(value, Section):
        return value.to_dict()
    if isinstance(value, Mapping):
        return {k: thawed(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [thawed(v) for v in value]
    return value


@dataclass(frozen=True, kw_only=True)
class Section:
    """One JSON object of bundle.json, typed. Subclasses declare their fields (named as the JSON
    keys) and :meth:`_typed`, which reads and checks them; :meth:`parse` and :meth:`to_dict` do the rest."""

    extra: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    #: the JSON keys in the order read (the order written back); not part of the value
    order: tuple[str, ...] = field(default=(), compare=False, repr=False)
    NULLABLE: ClassVar[frozenset[str]] = frozenset()

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        """The typed fields' values read from ``data`` (the JSON object at ``where``), checked."""
        raise NotImplementedError

    @classmethod
    def parse(cls, data: object, where: str) -> Self:
        """The section read from the JSON object ``data`` found at ``where`` (for messages), checked:
        a :class:`ManifestFieldError` naming the field where one is missing or wrong."""
        if not isinstance(data, Mapping):
            raise ManifestFieldError(f"{where!r} must be an object, got {data!r}")
        typed = cls._typed(data, where)
        names = cls.field_names()
        extra = {k: v for k, v in data.items() if k not in names}
        return cls(**typed, extra=frozen(extra), order=tuple(data))

    @classmethod
    def from_report(cls, value: Mapping[str, Any], where: str) -> Self:
        """The section of a value computed in memory (a training's entry, a calibration's record)
        as bundle.json will hold it: :func:`as_json` first, then :meth:`parse`."""
        return cls.parse(as_json(value), where)

    @classmethod
    def field_names(cls) -> frozenset[str]:
        """The JSON keys this section types."""
        return frozenset(f.name for f in fields(cls) if f.name not in _BOOKKEEPING)

    def to_dict(self) -> dict[str, Any]:
        """The section as JSON: what :meth:`parse` read, in its order, with any field replaced since
        (and fields set since, after them)."""
        values = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in _BOOKKEEPING or (value is None and not self._null_kept(f.name)):
                continue
            values[f.name] = thawed(value)
        values.update(thawed(self.extra))
        ordered = {k: values[k] for k in self.order if k in values}
        return {**ordered, **{k: v for k, v in values.items() if k not in ordered}}

    def _null_kept(self, name: str) -> bool:
        return name in self.NULLABLE and name in self.order


# -- the checks of one JSON value; each raises ManifestFieldError naming ``where``


def number(value: object, where: str, *, low: float | None = None, optional: bool = False) -> Any:
    """A finite number (at least ``low``), kept as read (an int stays an int: the JSON round trip)."""
    if value is None and optional:
        return None
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    if not ok or (low is not None and value < low):
        bound = f" >= {low:g}" if low is not None else ""
        raise ManifestFieldError(f"{where!r} must be a finite number{bound}, got {value!r}")
    return value


def whole(value: object, where: str, *, optional: bool = False) -> int | None:
    """A whole number (JSON integer)."""
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise ManifestFieldError(f"{where!r} must be a whole number, got {value!r}")
    return value


def text(value: object, where: str, *, optional: bool = False) -> str | None:
    """A string."""
    if value is None and optional:
        return None
    if not isinstance(value, str):
        raise ManifestFieldError(f"{where!r} must be a string, got {value!r}")
    return value


def flag(value: object, where: str) -> bool | None:
    """A boolean, or None where absent."""
    if value is not None and not isinstance(value, bool):
        raise ManifestFieldError(f"{where!r} must be true or false, got {value!r}")
    return value


def mapping(value: object, where: str, *, optional: bool = False) -> Mapping[str, Any] | None:
    """A JSON object, read-only."""
    if value is None and optional:
        return None
    if not isinstance(value, Mapping):
        raise ManifestFieldError(f"{where!r} must be an object, got {value!r}")
    return frozen(value)


def whole_list(value: object, where: str, *, optional: bool = False) -> tuple[int, ...] | None:
    """A list of whole numbers, as a tuple."""
    if value is None and optional:
        return None
    if not isinstance(value, list) or not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise ManifestFieldError(f"{where!r} must be a list of whole numbers, got {value!r}")
    return tuple(value)
