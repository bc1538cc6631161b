"""The mannequin: the default body, the canonical skeleton with the default capsules, that a
sequence naming no body stands on and a model trained on no other body animates on."""

from __future__ import annotations

from ..motion.skeleton import CANONICAL, REST_PELVIS_HEIGHT
from .body_file import BodyRecord
from .capsules import DEFAULT_BODY

MANNEQUIN = "mannequin"  # the name of the default body (sequences that name no body stand on it)
MANNEQUIN_STATURE_M = 1.70


def mannequin_record() -> BodyRecord:
    """The mannequin as a body record (the canonical skeleton and the default capsules)."""
    return BodyRecord(CANONICAL, DEFAULT_BODY, pelvis_height=REST_PELVIS_HEIGHT, stature=MANNEQUIN_STATURE_M)
