"""Capsule body: posing, signed distance, preview mesh."""

from .capsules import (
    DEFAULT_BODY,
    BodyModel,
    Capsule,
    body_mesh,
    capsule_signed_distance,
)

__all__ = ["BodyModel", "Capsule", "DEFAULT_BODY", "body_mesh", "capsule_signed_distance"]
