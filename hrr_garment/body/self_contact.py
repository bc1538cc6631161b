"""Frames where the motion's own limbs pass through the body: a flaw of the capture, not the cloth.

Real motion capture puts a hand into the hip or one shin through the other now and then (marker
noise, a hand on the hip solved too deep, retargeting onto other proportions). Cloth caught between
two capsules that overlap cannot stay outside both, so penetration on those frames says nothing
about the simulator. A frame is flagged when a forearm or hand sinks into the torso or a thigh, an
upper arm into the chest, or a leg into the other leg, by more than ``depth`` (default 2.5 cm: more
than soft tissue gives),
together with the rest of that episode (from the moment the cloth between limb and body is caught)
and the frames the cloth needs to get back out.
Measured: Bandai-Namco clips stay under 3 cm on every frame and mostly at 0; CMU 131_01, a hand on
the hip, reaches 10.7 cm; CMU 131_03's right upper arm sinks 3.7 cm into the chest (frames 202-215),
while over the whole real-quick library upper arms pass 2.5 cm on 2 frames of 114,066.
"""

from __future__ import annotations

import numpy as np

from ..motion.motion import Motion
from .capsules import DEFAULT_BODY, BodyModel

TORSO = ("hips", "belly", "chest", "upper_chest")
UPPER_ARM = ("upper_arm",)
LOWER_ARM = ("forearm", "hand")
LEG_PARTS = ("thigh", "shin")
LIMB_PARTS = UPPER_ARM + LOWER_ARM + LEG_PARTS  # every limb the flags look at
AXIS_SAMPLES = 5  # points along each limb's axis


def _pairs(body: BodyModel, parts: tuple[str, ...]) -> list[tuple[int, list[int], float]]:
    """(limb capsule, capsules its axis must stay out of, where along its axis the samples start)
    by index into ``body.capsules``, for the limbs named in ``parts``. An upper arm is sampled from
    a quarter of its length on: its shoulder end sits in the torso's shoulder by construction."""
    index = {c.name: i for i, c in enumerate(body.capsules)}
    pairs = []
    for side, other in (("l", "r"), ("r", "l")):
        targets = [index[n] for n in (*TORSO, f"{side}_thigh", f"{other}_thigh") if n in index]
        torso = [index[n] for n in TORSO if n in index]
        pairs += [
            (index[f"{side}_{p}"], torso, 0.25) for p in UPPER_ARM if f"{side}_{p}" in index and p in parts
        ]
        pairs += [
            (index[f"{side}_{p}"], targets, 0.0) for p in LOWER_ARM if f"{side}_{p}" in index and p in parts
        ]
        legs = [index[f"{other}_{p}"] for p in LEG_PARTS if f"{other}_{p}" in index]
        pairs += [
            (index[f"{side}_{p}"], legs, 0.0) for p in LEG_PARTS if f"{side}_{p}" in index and p in parts
        ]
    return pairs


def limb_intrusions(
    motion: Motion, body: BodyModel = DEFAULT_BODY, parts: tuple[str, ...] = LIMB_PARTS
) -> np.ndarray:
    """(L, T) metres by which each limb's surface sinks deepest into a capsule it should stay out
    of, negative for the gap between their surfaces where they do not overlap: sampled along the
    limb's axis. One row per limb named in ``parts`` (left and right)."""
    a, b = body.pose_motion(motion)
    radii = body.radii
    rows = []
    for limb, targets, first in _pairs(body, parts):
        t = np.linspace(first, 1.0, AXIS_SAMPLES)
        points = a[:, limb, None] + t[None, :, None] * (b[:, limb] - a[:, limb])[:, None]  # (T, S, 3)
        ta, tb = a[:, targets], b[:, targets]  # (T, K, 3)
        ab = tb - ta
        rel = points[:, :, None] - ta[:, None]  # (T, S, K, 3)
        s = np.clip((rel * ab[:, None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12)[:, None], 0.0, 1.0)
        dist = np.linalg.norm(rel - s[..., None] * ab[:, None], axis=-1)  # (T, S, K)
        rows.append((radii[targets][None, None] + radii[limb] - dist).max(axis=(1, 2)))
    return np.array(rows).reshape(len(rows), motion.num_frames)


def limb_intrusion(
    motion: Motion, body: BodyModel = DEFAULT_BODY, parts: tuple[str, ...] = LIMB_PARTS
) -> np.ndarray:
    """(T,) the deepest of :func:`limb_intrusions` on each frame."""
    rows = limb_intrusions(motion, body, parts)
    return rows.max(axis=0) if len(rows) else np.full(motion.num_frames, -np.inf)


SELF_INTERSECTION_DEPTH = 0.025  # metres: deeper than soft tissue gives
# metres: an episode starts and ends where the cloth no longer fits between limb and body (the
# simulator's particles are 6 mm in radius)
PINCH_GAP = 0.012
RECOVERY_S = 0.1  # seconds after an episode during which the cloth it trapped is pushed back out


def self_intersection_episodes(
    motion: Motion,
    body: BodyModel = DEFAULT_BODY,
    depth: float = SELF_INTERSECTION_DEPTH,
    gap: float = PINCH_GAP,
    recovery_s: float = RECOVERY_S,
    parts: tuple[str, ...] = LIMB_PARTS,
) -> list[tuple[int, int]]:
    """(start, stop) frame ranges of the episodes in which a limb sinks more than ``depth`` metres
    into the body (a flaw of the capture), ``stop`` one past the last frame.

    An episode runs from the frame the limb comes within ``gap`` metres of the body (the cloth
    between them is caught from there on) to the frame it is that far away again, plus
    ``recovery_s`` seconds: cloth pinched between two overlapping capsules is pushed out by contact
    forces over a few frames, not at once (131_03: 1.3 % of the dress still inside two frames after
    the hand left the hip). Episodes that never pass ``depth`` (a hand resting lightly on the hip)
    are not returned; overlapping ranges are merged. ``parts``: the limbs to look at.
    """
    recovery = int(round(recovery_s * motion.fps))
    # Forearms, hands and legs together; each upper arm on its own, because an upper arm rests
    # within the pinch gap of the chest on most frames and would join every other episode.
    limbs = tuple(p for p in parts if p not in UPPER_ARM)
    signals = [limb_intrusion(motion, body, limbs)] if limbs else []
    signals += list(limb_intrusions(motion, body, tuple(p for p in parts if p in UPPER_ARM)))
    found: list[tuple[int, int]] = []
    for intrusion in signals:
        near = np.concatenate([[False], intrusion > -gap, [False]])
        starts = np.flatnonzero(~near[:-1] & near[1:])
        stops = np.flatnonzero(near[:-1] & ~near[1:])  # one past each episode's last frame
        found += [
            (int(start), min(int(stop) + recovery, len(intrusion)))
            for start, stop in zip(starts, stops)
            if intrusion[start:stop].max() > depth
        ]
    episodes: list[tuple[int, int]] = []
    for start, stop in sorted(found):
        if episodes and start <= episodes[-1][1]:
            episodes[-1] = (episodes[-1][0], max(stop, episodes[-1][1]))
        else:
            episodes.append((start, stop))
    return episodes


def self_intersecting_frames(
    motion: Motion,
    body: BodyModel = DEFAULT_BODY,
    depth: float = SELF_INTERSECTION_DEPTH,
    gap: float = PINCH_GAP,
    recovery_s: float = RECOVERY_S,
    parts: tuple[str, ...] = LIMB_PARTS,
) -> np.ndarray:
    """(T,) True on the frames of :func:`self_intersection_episodes`."""
    flagged = np.zeros(motion.num_frames, bool)
    for start, stop in self_intersection_episodes(motion, body, depth, gap, recovery_s, parts):
        flagged[start:stop] = True
    return flagged
