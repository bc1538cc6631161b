"""A body as a few numbers: the vector a garment model is conditioned on, and the range it knows.

    vector = body_vector(record)                  # (12,) metres: stature, pelvis, limbs, widths, girths
    known = BodyRange.of([body_vector(r) for r in training_bodies])
    known.outside(vector)                         # [] inside; else one line per measure outside

The model sees a body once per character, not per vertex per frame: these measures are appended
to every motion frame's features (the motion encoder reads them, and the code space's garment
encoder and decoder take them from the window). They are what the garment responds to: how tall
the body is and where its pelvis hangs the garment (stature, pelvis height), its limbs' lengths
(the swing of the legs under a skirt; the arms' reach), its widths and its girths (the capsules'
radii at the hips, belly, chest and thighs: how far out the cloth sits). Every one is read from a
:class:`~.body_file.BodyRecord`, so a fitted character, a parametric body and the mannequin are
measured alike.

A model records the range of its training bodies (:class:`BodyRange`); a body outside it by more
than a tenth of the range's span is a body the model never saw the like of, and is refused (or,
when asked, warned about) by the caller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .body_file import BodyRecord
from .proportions import MEASURES, proportions

GIRTHS = {
    "hips_radius": ("hips",),
    "belly_radius": ("belly",),
    "chest_radius": ("chest",),
    "thigh_radius": ("l_thigh", "r_thigh"),
}  # measure: the capsules whose radii it averages
BODY_MEASURES = ("stature", "pelvis_height", *MEASURES, *GIRTHS)
RANGE_MARGIN = (
    0.1  # of each measure's span across the training bodies: how far out a body still counts as known
)


def body_vector(record: BodyRecord) -> np.ndarray:
    """(len(BODY_MEASURES),) float32 the body's measures in metres, in :data:`BODY_MEASURES`' order."""
    lengths = proportions(record.skeleton.rest_positions())
    radii = {c.name: c.radius for c in record.body.capsules}
    missing = sorted({n for names in GIRTHS.values() for n in names} - set(radii))
    if missing:
        raise ValueError(f"the body has no capsule named {', '.join(missing)}: its girths cannot be measured")
    girths = {k: float(np.mean([radii[n] for n in names])) for k, names in GIRTHS.items()}
    values = {"stature": record.stature, "pelvis_height": record.pelvis_height, **lengths, **girths}
    return np.array([values[k] for k in BODY_MEASURES], np.float32)


def with_columns(features: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Per-frame motion features (T, F) with a conditioning vector (a body's measures, a cloth's
    values) appended to every frame (T, F + b): ``vector`` (b,) one for all, or (T, b) one per row
    (a crowd's characters)."""
    features = np.asarray(features)
    vector = np.asarray(vector, features.dtype)
    return np.concatenate([features, np.broadcast_to(vector, (len(features), vector.shape[-1]))], 1)


@dataclass(frozen=True)
class BodyRange:
    """Each measure's lowest and highest value over the bodies a model was trained on."""

    low: tuple[float, ...]
    high: tuple[float, ...]
    bodies: int  # how many bodies span it
    names: tuple[str, ...] = BODY_MEASURES

    @classmethod
    def of(cls, vectors: list[np.ndarray]) -> "BodyRange":
        v = np.asarray(vectors, np.float64).reshape(len(vectors), -1)
        return cls(tuple(v.min(0).round(5).tolist()), tuple(v.max(0).round(5).tolist()), len(v))

    def outside(self, vector: np.ndarray, margin: float = RANGE_MARGIN) -> list[str]:
        """One line per measure of ``vector`` outside the range widened by ``margin`` of its span
        (at least a centimetre); empty when the body is within it."""
        lines = []
        for name, lo, hi, x in zip(self.names, self.low, self.high, np.asarray(vector, np.float64)):
            slack = max(margin * (hi - lo), 0.01)
            if not lo - slack <= x <= hi + slack:
                lines.append(f"{name} {x:.3f} m, trained on {lo:.3f}-{hi:.3f} m")
        return lines

    def to_dict(self) -> dict:
        return {
            "names": list(self.names),
            "low": list(self.low),
            "high": list(self.high),
            "bodies": self.bodies,
        }

    @classmethod
    def from_dict(cls, data: dict) -> "BodyRange":
        names = tuple(data["names"])
        if names != BODY_MEASURES:
            raise ValueError(f"body measures {list(names)} are not this version's {list(BODY_MEASURES)}")
        low, high = tuple(map(float, data["low"])), tuple(map(float, data["high"]))
        bodies = data["bodies"]
        if not (len(low) == len(high) == len(names) and all(map(math.isfinite, low + high))):
            raise ValueError(f"a range needs {len(names)} finite low and high measures")
        if not all(a <= b for a, b in zip(low, high)) or not isinstance(bodies, int) or bodies < 1:
            raise ValueError("a range's lows lie at or below its highs, over at least one body")
        return cls(low, high, bodies, names)
