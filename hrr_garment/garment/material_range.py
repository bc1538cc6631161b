"""A cloth as the few numbers a garment model is conditioned on, and the range of cloths it knows.

    vector = material_vector(FABRICS["silk"])       # (5,): log10 density, stretch, shear, bend; damping
    known = MaterialRange.of([material_vector(m) for m in training_cloths])
    known.outside(vector)                           # [] inside; else one line per value outside

A model trained in several cloths reads this vector beside the body's measures, after every motion
frame's features (:mod:`hrr_garment.models.codespace`), as a body's measures are read. Densities,
stiffnesses and bending span one to two orders of magnitude across real fabrics, and the cloth's
response goes with their ratios (a fold's length with (bend / density)^(1/3), a stretch wave's speed
with sqrt(stretch / density)), so the model reads their logarithms; the damping is a time and
is read as it is.

A model records the range of its training cloths (:class:`MaterialRange`); a cloth outside it by
more than a tenth of the range's span is one the model never saw the like of, and is refused (or,
when asked, warned about) by the caller. A value every training cloth shares (the damping, so far;
every value of a model of one cloth) has no span: any other value of it is outside, since the model
never learned what it does (standardised over no spread, a hundredth of a second would read as ten
deviations).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .material import UNITS, Material

#: the vector's values, in order: the first four are log10 of the material's value, the last as it is
MATERIAL_FEATURES = ("density", "stretch", "shear", "bend", "damping")
LOGARITHMIC = frozenset({"density", "stretch", "shear", "bend"})
# of each value's span across the training cloths: how far out a cloth still counts as known
RANGE_MARGIN = 0.1
SAME = 1e-5  # how near a value must be to one every training cloth shares (rounding of the stored range)


def material_vector(material: Material) -> np.ndarray:
    """(len(MATERIAL_FEATURES),) float32: the material's values as the model reads them."""
    return np.array(
        [
            math.log10(getattr(material, k)) if k in LOGARITHMIC else getattr(material, k)
            for k in MATERIAL_FEATURES
        ],
        np.float32,
    )


def _physical(name: str, value: float) -> float:
    return 10.0**value if name in LOGARITHMIC else value


@dataclass(frozen=True)
class MaterialRange:
    """Each value's lowest and highest (as :func:`material_vector` has it) over the cloths a model
    was trained in."""

    low: tuple[float, ...]
    high: tuple[float, ...]
    cloths: int  # how many distinct cloths span it

    @classmethod
    def of(cls, vectors: list[np.ndarray]) -> "MaterialRange":
        v = np.asarray(vectors, np.float64).reshape(len(vectors), len(MATERIAL_FEATURES))
        distinct = len(np.unique(v.round(6), axis=0))
        return cls(tuple(v.min(0).round(6).tolist()), tuple(v.max(0).round(6).tolist()), distinct)

    def outside(self, vector: np.ndarray, margin: float = RANGE_MARGIN) -> list[str]:
        """One line per value of ``vector`` outside the range widened by ``margin`` of its span;
        empty when the cloth is within it. Values are shown in their physical units."""
        lines = []
        for name, lo, hi, x in zip(MATERIAL_FEATURES, self.low, self.high, np.asarray(vector, np.float64)):
            slack = max(margin * (hi - lo), SAME)
            if not lo - slack <= x <= hi + slack:
                lines.append(
                    f"{name} {_physical(name, x):.3g} {UNITS[name]}, trained on "
                    f"{_physical(name, lo):.3g}-{_physical(name, hi):.3g} {UNITS[name]}"
                )
        return lines

    def to_dict(self) -> dict:
        return {
            "names": list(MATERIAL_FEATURES),
            "low": list(self.low),
            "high": list(self.high),
            "cloths": self.cloths,
        }

    @classmethod
    def from_dict(cls, data: dict) -> "MaterialRange":
        names = tuple(data["names"])
        if names != MATERIAL_FEATURES:
            raise ValueError(
                f"material values {list(names)} are not this version's {list(MATERIAL_FEATURES)}"
            )
        low, high = tuple(map(float, data["low"])), tuple(map(float, data["high"]))
        cloths = data["cloths"]
        if not (len(low) == len(high) == len(names) and all(map(math.isfinite, low + high))):
            raise ValueError(f"a material range needs {len(names)} finite low and high values")
        if not all(a <= b for a, b in zip(low, high)) or not isinstance(cloths, int) or cloths < 1:
            raise ValueError("a material range's lows lie at or below its highs, over at least one cloth")
        return cls(low, high, cloths)
