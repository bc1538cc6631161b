"""bundle.json's ``auto``, typed (:mod:`.manifest_section`): what the auto calibration
(:mod:`hrr_garment.eval.auto_mode`) chose and every candidate's numbers it chose on.

Absent until training calibrates it; :data:`UNCALIBRATED` stands for it until then (the hybrid,
with the default detail look). A manifest from before a field arrived lacks it (None here): the
calibration's staleness checks (:mod:`hrr_garment.eval.auto_mode`) read that as "measured before".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Self

from .manifest import (
    AUTO_CHOICES,
    DETAIL_BASES,
    MAX_DETAIL_STRENGTH,
    UNCALIBRATED_AUTO,
    valid_detail_strength,
)
from .manifest_section import ManifestFieldError, Section, flag, mapping, number, text, whole

FreeCloth = tuple[float, float]  # a free-cloth ramp: (lo, hi) mm from the body, lo < hi


@dataclass(frozen=True, kw_only=True)
class AutoCalibration(Section):
    """``auto``: the mode ``auto`` runs and the detail look, the free-cloth ramps and swing gain
    chosen with it, the candidates' numbers, and what they were measured on and under."""

    mode: str
    detail_base: str
    detail_strength: float
    residual_free_mm: FreeCloth | None = None  # None: the residual everywhere
    folds_free_mm: FreeCloth | None = None  # None: the folds everywhere
    swing_gain: float | None = None  # None: 1, the swing as predicted
    candidates: Mapping[str, Mapping[str, float]] | None = None  # label: its numbers
    criterion: str | None = None
    allowance: float | None = None
    penetration_allowance: float | None = None
    penetration_floor_pct: float | None = None
    sequences: int | None = None
    frames: int | None = None
    fold_follow: float | None = None
    folds_free_cloth: bool | None = None
    default_body_sequences: int | None = None
    swing_half_life_s: float | None = None
    sampler_key: str | None = None  # the generative decoder the sample mode's numbers are of (its key)
    NULLABLE = frozenset({"residual_free_mm", "folds_free_mm"})

    @classmethod
    def parse(cls, data: object, where: str = "auto") -> Self:
        """``auto`` read from its JSON object, checked (the mode and detail look first)."""
        if not isinstance(data, Mapping) or data.get("mode") not in AUTO_CHOICES:
            raise ManifestFieldError(f"'auto' must hold a 'mode' of {', '.join(AUTO_CHOICES)}, got {data!r}")
        return super().parse(data, where)

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        if data.get("detail_base") not in DETAIL_BASES:
            raise ManifestFieldError(
                f"'auto' 'detail_base' must be one of {', '.join(DETAIL_BASES)}, got "
                f"{data.get('detail_base')!r}"
            )
        if not valid_detail_strength(data.get("detail_strength")):
            raise ManifestFieldError(
                f"'auto' 'detail_strength' must be a number in (0, {MAX_DETAIL_STRENGTH:g}], "
                f"got {data.get('detail_strength')!r}"
            )
        return {
            "mode": data["mode"],
            "detail_base": data["detail_base"],
            "detail_strength": data["detail_strength"],
            "residual_free_mm": _ramp(data.get("residual_free_mm"), "residual_free_mm"),
            "folds_free_mm": _ramp(data.get("folds_free_mm"), "folds_free_mm"),
            "swing_gain": number(data.get("swing_gain"), f"{where}.swing_gain", optional=True),
            "candidates": mapping(data.get("candidates"), f"{where}.candidates", optional=True),
            "criterion": text(data.get("criterion"), f"{where}.criterion", optional=True),
            "sampler_key": text(data.get("sampler_key"), f"{where}.sampler_key", optional=True),
            **{
                key: number(data.get(key), f"{where}.{key}", optional=True)
                for key in ("allowance", "penetration_allowance", "penetration_floor_pct", "fold_follow")
            },
            **{
                key: whole(data.get(key), f"{where}.{key}", optional=True)
                for key in ("sequences", "frames", "default_body_sequences")
            },
            "folds_free_cloth": flag(data.get("folds_free_cloth"), f"{where}.folds_free_cloth"),
            "swing_half_life_s": number(
                data.get("swing_half_life_s"), f"{where}.swing_half_life_s", optional=True
            ),
        }


def _ramp(value: object, key: str) -> FreeCloth | None:
    """A free-cloth ramp: null, or [lo, hi] mm with lo < hi."""
    if value is None:
        return None
    if not (
        isinstance(value, list)
        and len(value) == 2
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)
        and math.isfinite(value[0])
        and math.isfinite(value[1])
        and value[0] < value[1]
    ):
        raise ManifestFieldError(f"'auto' {key!r} must be null or [lo, hi] mm with lo < hi, got {value!r}")
    return (value[0], value[1])


#: what ``auto`` stands for until training calibrates it: the hybrid, with the default detail look
UNCALIBRATED = AutoCalibration.parse(UNCALIBRATED_AUTO)
