"""glTF 2.0 / GLB files as canonical motion: a skin's joints and one of the file's animations (read
by :mod:`.gltf_animation`).

The file is read with pygltflib (the ``export`` extra). The skin's joints are nodes with names,
parents and rest transforms; the animation's channels key their translation, rotation and scale
(LINEAR, STEP or CUBICSPLINE). The channels are evaluated at 30 fps over the animation's time span,
world transforms are composed through the whole node tree (so an armature node above the root
joint, scaled to centimetres or turned from Z up, is applied: positions come out in metres), and
each joint's world rotation is taken relative to its rest one, which makes the rest pose the source
skeleton's zero pose as a BVH's offsets are. From there the clip takes the BVH path: joint names
through :mod:`.joint_maps`, retargeting by :mod:`.retarget`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bvh_motion import PLAUSIBLE_HEIGHT_M, check_unit_scale, detect_unit_scale
from .gltf_animation import AnimationChannel, animation_names, pick_animation, read_channels, sample_channel
from .gltf_file import (
    GltfDocument,
    node_chain,
    node_parents,
    rest_trs,
    rest_world,
    rotation_part,
    world_transforms,
)
from .joint_maps import resolve_joint_map
from .limits import MAX_JOINTS, MAX_SOURCE_FPS, check_frame_budget
from .motion import FPS, Motion
from .reference_frames import leading_reference_frames
from .resample import frame_chunks, kernel_width, resample_linear, resample_rotations, resample_times
from .retarget import SourceMotion, check_source, retarget, standing_height_from_legs
from .skeleton_doubts import skeleton_doubts, warn_doubts


def _pick_skin(doc: GltfDocument, channels: list[AnimationChannel]) -> list[int]:
    """The joints (node indices) of the skin the channels animate most (the first of equals)."""
    skins = doc.doc.skins or []
    if not skins:
        raise doc.fail(
            "the file has no skin: motion is read from a skinned character's joints "
            "(animated nodes without a skin are not read)"
        )
    keyed = {c.node for c in channels}
    best = max(range(len(skins)), key=lambda s: (len(keyed & set(skins[s].joints or [])), -s))
    joints = list(skins[best].joints or [])
    if len(joints) > MAX_JOINTS:
        raise doc.fail(
            f"skin {best} has {len(joints)} joints, more than {MAX_JOINTS} (a human rig has under a few "
            "hundred)"
        )
    if not joints or not all(isinstance(j, int) and 0 <= j < len(doc.doc.nodes) for j in joints):
        raise doc.fail(f"skin {best} has no joints or names nodes that are missing")
    if not keyed & set(joints):
        raise doc.fail(f"the animation keys none of skin {best}'s {len(joints)} joints")
    return joints


def _key_rate(channels: list[AnimationChannel]) -> float | None:
    """The rate the densest channel is keyed at (from its median key spacing); None where no
    channel has three keys."""
    spacings = [float(np.median(np.diff(c.times))) for c in channels if len(c.times) >= 3]
    spacings = [d for d in spacings if d > 0]
    return 1.0 / min(spacings) if spacings else None


MAX_SECONDS_PER_KEY = 60.0  # between keys on average: hand-keyed animation keys every few frames


def _times(doc: GltfDocument, channels: list[AnimationChannel], fps: float) -> np.ndarray:
    """The output frame times: the animation's span at ``fps`` (its last partial frame left out, as
    other inputs are resampled)."""
    start = min(c.times[0] for c in channels)
    end = max(c.times[-1] for c in channels)
    frames = int(np.floor((end - start) * fps + 1e-4)) + 1
    check_frame_budget(doc.path, frames, fps, fps_out=fps)
    keys = max(len(c.times) for c in channels)
    if frames > max(keys, 2) * MAX_SECONDS_PER_KEY * fps:  # memory and time follow the file's content
        raise doc.fail(
            f"its animation spans {end - start:,.0f} s with {keys} keys in its densest channel: more than "
            f"{MAX_SECONDS_PER_KEY:g} s a key is no motion a file of keys holds"
        )
    return start + np.arange(frames) / fps


def _local_transforms(
    doc: GltfDocument, order: list[int], channels: list[AnimationChannel], times: np.ndarray
) -> dict[int, tuple]:
    """Each node's local (translation, rotation, scale) per frame: its channels where keyed, its
    rest transform elsewhere."""
    frames = len(times)
    local = {}
    for n in order:
        t, q, s = rest_trs(doc.doc.nodes[n])
        local[n] = {
            "translation": np.broadcast_to(t, (frames, 3)),
            "rotation": np.broadcast_to(q, (frames, 4)),
            "scale": np.broadcast_to(s, (frames, 3)),
        }
    for ch in channels:
        if ch.node in local:
            local[ch.node][ch.path] = sample_channel(ch, times)
    return {n: (v["translation"], v["rotation"], v["scale"]) for n, v in local.items()}


# frames composed a pass: every node of the chain's local and world transforms of a long clip at
# once would take gigabytes (a character's chain is 50-70 nodes; 8,192 frames of it ~ 0.1 GB)
WORLD_CHUNK = 8_192


def _joint_world(
    doc: GltfDocument,
    rig: tuple[list[int], list[int], list[int]],
    channels: list[AnimationChannel],
    times: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The joints' world rotations (F, J, 3, 3) and positions (F, J, 3) at ``times``, composed in
    passes of :data:`WORLD_CHUNK` frames; ``rig`` is (the node chain in order, every node's
    parent, the skin's joints). Memory follows the joints' output, not the chain's temporaries."""
    order, parents, joints = rig
    rot = np.empty((len(times), len(joints), 3, 3))
    pos = np.empty((len(times), len(joints), 3))
    for a, b in frame_chunks(len(times), WORLD_CHUNK):
        world = world_transforms(order, parents, _local_transforms(doc, order, channels, times[a:b]))
        rot[a:b] = np.stack([rotation_part(world[j][0]) for j in joints], 1)
        pos[a:b] = np.stack([world[j][1] for j in joints], 1)
    return rot, pos


@dataclass(frozen=True)
class GltfSettings:
    """How :func:`gltf_source` reads a file: which animation (name or index; None: the first),
    metres per file unit (None: the file's own metres, detected when implausible), a user joint map,
    the output frame rate."""

    animation: str | int | None = None
    unit_scale: float | None = None
    joint_map: dict | None = None
    fps: float = FPS


def gltf_source(
    path: str | Path, options: GltfSettings = GltfSettings()
) -> tuple[SourceMotion, str, dict[str, int], str]:
    """A glTF / GLB animation on its own skeleton, in metres, at ``options.fps``: (the motion, the
    naming scheme, canonical joint name -> source joint index, the animation's name)."""
    doc = GltfDocument(Path(path))
    index = pick_animation(doc, options.animation)
    channels = read_channels(doc, index)
    joints = _pick_skin(doc, channels)
    parents = node_parents(doc)
    names = [doc.doc.nodes[j].name or f"node_{j}" for j in joints]
    joint_parents = []
    for j in joints:
        p = parents[j]
        while p >= 0 and p not in joints:
            p = parents[p]
        joint_parents.append(joints.index(p) if p >= 0 else -1)
    scheme, mapping = resolve_joint_map(names, str(doc.path), options.joint_map)
    order = node_chain(parents, joints)
    times = _times(doc, channels, options.fps)
    # keyed much faster than the output (a 120 fps capture baked to keys): evaluated at its key
    # rate and low-pass filtered down, as a BVH of it is (.resample)
    rate = _key_rate(channels)
    if rate and rate > MAX_SOURCE_FPS:  # its low-pass filter would span millions of frames
        raise doc.fail(
            f"its keys lie {1 / rate:.3g} s apart: {rate:.3g} keys a second, more than {MAX_SOURCE_FPS:g}"
        )
    width = kernel_width(rate, options.fps) if rate else 1.0
    sampled = _times(doc, channels, rate) if width > 1.0 else times
    at_rest = rest_world(doc, order, parents)
    rest = np.stack([at_rest[j][1][0] for j in joints])
    scale = world_unit_scale(doc.path, rest, mapping, options.unit_scale)
    rest_rot = np.stack([rotation_part(at_rest[j][0][0]) for j in joints])
    g_rot, g_pos = _joint_world(doc, (order, parents, joints), channels, sampled)
    g_rot = g_rot @ np.swapaxes(rest_rot, -1, -2)
    g_pos *= scale
    # a conversion's T-pose before the motion is no part of it (.reference_frames)
    start = leading_reference_frames(g_rot, g_pos[:, mapping["pelvis"]], rate if width > 1.0 else options.fps)
    g_rot, g_pos, sampled = g_rot[start:], g_pos[start:], sampled[start:]
    if width > 1.0:
        frames = resample_times(len(sampled), rate, options.fps)
        g_rot, g_pos = resample_rotations(g_rot, frames, width), resample_linear(g_pos, frames, width)
    src = SourceMotion(
        names,
        joint_parents,
        rest * scale,
        global_rotations=g_rot,
        global_positions=g_pos,
        fps=options.fps,
        path=str(doc.path),
    )
    check_source(src)
    warn_doubts(str(doc.path), skeleton_doubts(names, joint_parents, rest=rest, mapping=mapping))
    return src, scheme, mapping, animation_names(doc)[index]


def world_unit_scale(
    path: Path,
    rest: np.ndarray,
    mapping: dict[str, int],
    unit_scale: float | None = None,
    *,
    shortest_m: float = PLAUSIBLE_HEIGHT_M[0],
) -> float:
    """Metres per unit of a glTF file's composed world positions: ``unit_scale`` when given; else 1
    (glTF is metres) unless the standing height of the rest joints ``rest`` is below ``shortest_m``
    or above the tallest plausible human in metres (a file written in centimetres without a scaling
    node), then the unit that height says (:func:`~.bvh_motion.detect_unit_scale`)."""
    if unit_scale is not None:
        return check_unit_scale(path, unit_scale, rest=rest, mapping=mapping)
    if shortest_m <= standing_height_from_legs(rest, mapping) <= PLAUSIBLE_HEIGHT_M[1]:
        return 1.0
    return detect_unit_scale(rest, mapping, path)


def load_gltf(path: str | Path, options: GltfSettings = GltfSettings(), ground: bool = True) -> Motion:
    """A glTF / GLB animation as canonical motion: retargeted, grounded, at ``options.fps``."""
    src, scheme, mapping, _ = gltf_source(path, options)
    local, root = retarget(src, mapping, ground=ground)
    return Motion(
        local,
        root,
        options.fps,
        source=str(path),
        source_skeleton=scheme,
        source_height_m=standing_height_from_legs(src.rest_positions, mapping),
    )
