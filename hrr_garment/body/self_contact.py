"""Frames where the motion's own limbs pass through the body: a flaw of the capture, not the cloth.

Real motion capture puts a hand into the hip or one shin through the other now and then (marker
noise, a hand on the hip solved too deep, retargeting onto other proportions). Cloth caught between
two capsules that overlap cannot stay outside both, so penetration on those frames says nothing
about the simulator. A frame is flagged when a forearm or hand sinks into the torso or a thigh, or
a leg into the other leg, by more than ``depth`` (default 2.5 cm: more than soft tissue gives),
together with the rest of that episode and the frames the cloth needs to get back out.
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


SELF_INTERSECTION_DEPTH = 0.025  # metres: deeper than soft tissue gives
CONTACT_DEPTH = 0.01  # metres: where an episode of a limb sinking into the body starts and ends
RECOVERY_S = 0.1  # seconds after an episode during which the cloth it trapped is pushed back out


def self_intersecting_frames(motion: Motion, body: BodyModel = DEFAULT_BODY,
                             depth: float = SELF_INTERSECTION_DEPTH, contact: float = CONTACT_DEPTH,
                             recovery_s: float = RECOVERY_S) -> np.ndarray:
    """(T,) True on the frames of each episode in which a limb sinks more than ``depth`` metres into
    the body (a flaw of the capture).

    An episode runs from the frame the limb first sinks ``contact`` metres in to the frame it is
    out again, plus ``recovery_s`` seconds: cloth pinched between two overlapping capsules is pushed
    out by contact forces over a few frames, not at once (CMU 131_03: 1.3 % of the dress still
    inside two frames after the hand left the hip, 0.96 % at most once those frames are counted
    with their episode). Episodes that never pass ``depth`` (a hand resting lightly on the hip)
    flag nothing.
    """
    intrusion = limb_intrusion(motion, body)
    flagged = np.zeros(len(intrusion), bool)
    recovery = int(round(recovery_s * motion.fps))
    touching = np.concatenate([[False], intrusion > contact, [False]])
    starts = np.flatnonzero(~touching[:-1] & touching[1:])
    stops = np.flatnonzero(touching[:-1] & ~touching[1:])  # one past each episode's last frame
    for start, stop in zip(starts, stops):
        if intrusion[start:stop].max() > depth:
            flagged[start:stop + recovery] = True
    return flagged
