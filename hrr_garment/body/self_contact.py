"""Frames where the motion's own limbs pass through the body: a flaw of the capture, not the cloth.

Real motion capture puts a hand into the hip or one shin through the other now and then (marker
noise, a hand on the hip solved too deep, retargeting onto other proportions). Cloth caught between
two capsules that overlap cannot stay outside both, so penetration on those frames says nothing
about the simulator. A frame is flagged when a forearm or hand sinks into the torso or a thigh, or
a leg into the other leg, by more than ``depth`` (default 2.5 cm: more than soft tissue gives).
Measured: Bandai-Namco clips stay under 3 cm on every frame and mostly at 0; CMU 131_01, a hand on
the hip, reaches 10.7 cm.
"""

from __future__ import annotations

import numpy as np

from ..motion.motion import Motion
from .capsules import DEFAULT_BODY, BodyModel

TORSO = ("hips", "belly", "chest", "upper_chest")
ARM_PARTS = ("forearm", "hand")
LEG_PARTS = ("thigh", "shin")
AXIS_SAMPLES = 5  # points along each limb's axis


def _pairs(body: BodyModel) -> list[tuple[int, list[int]]]:
    """(limb capsule, capsules its axis must stay out of) by index into ``body.capsules``."""
    index = {c.name: i for i, c in enumerate(body.capsules)}
    pairs = []
    for side, other in (("l", "r"), ("r", "l")):
        targets = [index[n] for n in (*TORSO, f"{side}_thigh", f"{other}_thigh") if n in index]
        pairs += [(index[f"{side}_{p}"], targets) for p in ARM_PARTS if f"{side}_{p}" in index]
        legs = [index[f"{other}_{p}"] for p in LEG_PARTS if f"{other}_{p}" in index]
        pairs += [(index[f"{side}_{p}"], legs) for p in LEG_PARTS if f"{side}_{p}" in index]
    return pairs


def limb_intrusion(motion: Motion, body: BodyModel = DEFAULT_BODY) -> np.ndarray:
    """(T,) metres by which a limb's surface sinks deepest into a capsule it should stay out of
    (0 where they do not overlap): sampled along the limb's axis."""
    a, b = body.pose_motion(motion)
    radii = body.radii
    t = np.linspace(0.0, 1.0, AXIS_SAMPLES)
    deepest = np.zeros(motion.num_frames)
    for limb, targets in _pairs(body):
        points = a[:, limb, None] + t[None, :, None] * (b[:, limb] - a[:, limb])[:, None]  # (T, S, 3)
        ta, tb = a[:, targets], b[:, targets]  # (T, K, 3)
        ab = tb - ta
        rel = points[:, :, None] - ta[:, None]  # (T, S, K, 3)
        s = np.clip((rel * ab[:, None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12)[:, None], 0.0, 1.0)
        dist = np.linalg.norm(rel - s[..., None] * ab[:, None], axis=-1)  # (T, S, K)
        inside = radii[targets][None, None] + radii[limb] - dist
        deepest = np.maximum(deepest, inside.max(axis=(1, 2)))
    return deepest


SELF_INTERSECTION_DEPTH = 0.025  # metres


def self_intersecting_frames(motion: Motion, body: BodyModel = DEFAULT_BODY,
                             depth: float = SELF_INTERSECTION_DEPTH) -> np.ndarray:
    """(T,) True where a limb sinks more than ``depth`` metres into the body (a flaw of the capture)."""
    return limb_intrusion(motion, body) > depth
