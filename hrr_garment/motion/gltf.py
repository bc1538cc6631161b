"""glTF 2.0 / GLB files as canonical motion: a skin's joints and one of the file's animations.

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

from ..errors import MotionError
from .bvh_motion import PLAUSIBLE_HEIGHT_M, detect_unit_scale
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
from .limits import MAX_BVH_JOINTS, check_frame_budget
from .motion import FPS, Motion
from .retarget import SourceMotion, check_source, retarget, standing_height_from_legs
from .rotations import quat_slerp
from .skeleton_doubts import skeleton_doubts, warn_doubts

_PATH_WIDTHS = {"translation": 3, "rotation": 4, "scale": 3}
_INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")


@dataclass(frozen=True)
class GltfAnimation:
    """One animation of a file: its name (``#index`` when it has none), index, time span and keys."""

    name: str
    index: int
    duration_s: float
    keyframes: int  # the most keys of any of its channels
    channels: int

    def as_dict(self) -> dict:
        """The animation as hrr-motion info prints it."""
        return {
            "name": self.name,
            "index": self.index,
            "duration_s": round(self.duration_s, 4),
            "keyframes": self.keyframes,
            "frames_30fps": int(np.floor(self.duration_s * FPS + 1e-4)) + 1,
            "channels": self.channels,
        }


@dataclass
class _Channel:
    """One animation channel, read: the node it keys, which property, key times and values."""

    node: int
    path: str  # translation / rotation / scale
    times: np.ndarray  # (K,) seconds
    values: np.ndarray  # (K, W), or (K, 3, W) for CUBICSPLINE (in-tangent, value, out-tangent)
    interpolation: str


def _animation_names(doc: GltfDocument) -> list[str]:
    return [a.name or f"#{i}" for i, a in enumerate(doc.doc.animations or [])]


def _pick_animation(doc: GltfDocument, animation: str | int | None) -> int:
    """The index of the animation asked for: by name first, then by index; the first by default."""
    names = _animation_names(doc)
    if not names:
        raise doc.fail(
            "the file has no animations (a glTF motion is read from an animation of a skinned character)"
        )
    listing = ", ".join(f"{i}: {n!r}" for i, n in enumerate(names))
    if animation is None:
        return 0
    if isinstance(animation, str) and animation in names:
        return names.index(animation)
    try:
        index = int(animation)
    except (TypeError, ValueError):
        raise doc.fail(f"no animation named {animation!r}; the file's animations are {listing}") from None
    if not 0 <= index < len(names):
        raise doc.fail(f"no animation {animation!r}; the file's animations are {listing}")
    return index


def _channels(doc: GltfDocument, index: int) -> list[_Channel]:
    """The translation / rotation / scale channels of animation ``index``, read and checked (morph
    target weights and extensions' targets are left out)."""
    anim = doc.doc.animations[index]
    out = []
    for c, channel in enumerate(anim.channels or []):
        target = channel.target
        if target is None or target.node is None or target.path not in _PATH_WIDTHS:
            continue
        try:
            sampler = anim.samplers[channel.sampler]
        except (IndexError, TypeError):
            raise doc.fail(
                f"animation {index} channel {c} names sampler {channel.sampler}, which is missing"
            ) from None
        interpolation = sampler.interpolation or "LINEAR"
        if interpolation not in _INTERPOLATIONS:
            raise doc.fail(f"animation {index} channel {c}: unknown interpolation {interpolation!r}")
        times = doc.accessor(sampler.input)[:, 0]
        values = doc.accessor(sampler.output)
        width = _PATH_WIDTHS[target.path]
        per_key = 3 if interpolation == "CUBICSPLINE" else 1
        if (
            len(times) == 0
            or values.shape != (len(times) * per_key, width)
            or not (np.diff(times) >= 0).all()
        ):
            raise doc.fail(
                f"animation {index} channel {c} ({target.path} of node {target.node}): "
                f"{len(times)} key times (must increase) for {values.shape[0]} values of width {values.shape[1]}"
            )
        if target.path == "rotation":
            values = values[:, [3, 0, 1, 2]]  # glTF quaternions are x, y, z, w
        if per_key == 3:
            values = values.reshape(len(times), 3, width)
        out.append(_Channel(target.node, target.path, times, values, interpolation))
    return out


def _sample(ch: _Channel, times: np.ndarray) -> np.ndarray:
    """A channel's value at ``times`` (F,) by its interpolation; held constant outside its keys."""
    keys = ch.times
    tol = 1e-6 * (1.0 + np.abs(times))  # key times stored as float32 still land on their frame
    if ch.interpolation == "STEP" or len(keys) == 1:
        idx = np.clip(np.searchsorted(keys, times + tol, side="right") - 1, 0, len(keys) - 1)
        return ch.values[idx, 1] if ch.values.ndim == 3 else ch.values[idx]
    i = np.clip(np.searchsorted(keys, times, side="right") - 1, 0, len(keys) - 2)
    dt = keys[i + 1] - keys[i]
    u = np.clip((times - keys[i]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)[:, None]
    u = np.where((dt > 0)[:, None], u, 1.0)
    if ch.interpolation == "CUBICSPLINE":  # Hermite: values and tangents (per second) of the two keys
        v0, b0, a1, v1 = ch.values[i, 1], ch.values[i, 2], ch.values[i + 1, 0], ch.values[i + 1, 1]
        d = dt[:, None]
        out = (
            (2 * u**3 - 3 * u**2 + 1) * v0
            + (u**3 - 2 * u**2 + u) * d * b0
            + (-2 * u**3 + 3 * u**2) * v1
            + (u**3 - u**2) * d * a1
        )
        return out / np.linalg.norm(out, axis=-1, keepdims=True) if ch.path == "rotation" else out
    v0, v1 = ch.values[i], ch.values[i + 1]
    if ch.path == "rotation":
        return quat_slerp(v0, v1, u[:, 0])
    return (1.0 - u) * v0 + u * v1


def _describe(doc: GltfDocument, index: int) -> GltfAnimation:
    channels = _channels(doc, index)
    if not channels:
        return GltfAnimation(_animation_names(doc)[index], index, 0.0, 0, 0)
    start = min(c.times[0] for c in channels)
    end = max(c.times[-1] for c in channels)
    return GltfAnimation(
        _animation_names(doc)[index],
        index,
        float(end - start),
        max(len(c.times) for c in channels),
        len(channels),
    )


def gltf_animations(path: str | Path) -> list[GltfAnimation]:
    """The animations of a glTF / GLB file: names, durations, key counts (hrr-motion info)."""
    doc = GltfDocument(Path(path))
    return [_describe(doc, i) for i in range(len(doc.doc.animations or []))]


def gltf_summary(path: str | Path, animation: str | int | None = None) -> dict:
    """The animation :func:`load_gltf` reads for ``animation`` and all of the file's animations."""
    doc = GltfDocument(Path(path))
    index = _pick_animation(doc, animation)
    return {
        "animation": _animation_names(doc)[index],
        "animations": [_describe(doc, i).as_dict() for i in range(len(doc.doc.animations))],
    }


# --- the skin and its motion -------------------------------------------------------------------------


def _pick_skin(doc: GltfDocument, channels: list[_Channel]) -> list[int]:
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
    if len(joints) > MAX_BVH_JOINTS:
        raise doc.fail(
            f"skin {best} has {len(joints)} joints, more than {MAX_BVH_JOINTS} (a human rig has under a few hundred)"
        )
    if not joints or not all(isinstance(j, int) and 0 <= j < len(doc.doc.nodes) for j in joints):
        raise doc.fail(f"skin {best} has no joints or names nodes that are missing")
    if not keyed & set(joints):
        raise doc.fail(f"the animation keys none of skin {best}'s {len(joints)} joints")
    return joints


def _times(doc: GltfDocument, channels: list[_Channel], fps: float) -> np.ndarray:
    """The output frame times: the animation's span at ``fps`` (its last partial frame left out, as
    other inputs are resampled)."""
    start = min(c.times[0] for c in channels)
    end = max(c.times[-1] for c in channels)
    frames = int(np.floor((end - start) * fps + 1e-4)) + 1
    check_frame_budget(doc.path, frames, fps, fps_out=fps)
    return start + np.arange(frames) / fps


def _local_transforms(
    doc: GltfDocument, order: list[int], channels: list[_Channel], times: np.ndarray
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
            local[ch.node][ch.path] = _sample(ch, times)
    return {n: (v["translation"], v["rotation"], v["scale"]) for n, v in local.items()}


@dataclass(frozen=True)
class GltfOptions:
    """How :func:`gltf_source` reads a file: which animation (name or index; None: the first),
    metres per file unit (None: the file's own metres, detected when implausible), a user joint map,
    the output frame rate."""

    animation: str | int | None = None
    unit_scale: float | None = None
    joint_map: dict | None = None
    fps: float = FPS


def gltf_source(
    path: str | Path, options: GltfOptions = GltfOptions()
) -> tuple[SourceMotion, str, dict[str, int], str]:
    """A glTF / GLB animation on its own skeleton, in metres, at ``options.fps``: (the motion, the
    naming scheme, canonical joint name -> source joint index, the animation's name)."""
    doc = GltfDocument(Path(path))
    index = _pick_animation(doc, options.animation)
    channels = _channels(doc, index)
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
    world = world_transforms(order, parents, _local_transforms(doc, order, channels, times))
    at_rest = rest_world(doc, order, parents)
    rest = np.stack([at_rest[j][1][0] for j in joints])
    scale = world_unit_scale(doc.path, rest, mapping, options.unit_scale)
    rest_rot = np.stack([rotation_part(at_rest[j][0][0]) for j in joints])
    g_rot = np.stack([rotation_part(world[j][0]) for j in joints], 1) @ np.swapaxes(rest_rot, -1, -2)
    g_pos = np.stack([world[j][1] for j in joints], 1) * scale
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
    return src, scheme, mapping, _animation_names(doc)[index]


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
        if not (np.isfinite(unit_scale) and unit_scale > 0):
            raise MotionError(
                path, f"unit scale must be a positive number of metres per file unit, got {unit_scale}"
            )
        return float(unit_scale)
    if shortest_m <= standing_height_from_legs(rest, mapping) <= PLAUSIBLE_HEIGHT_M[1]:
        return 1.0
    return detect_unit_scale(rest, mapping, path)


def load_gltf(path: str | Path, options: GltfOptions = GltfOptions(), ground: bool = True) -> Motion:
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
