"""A glTF / GLB file's animations: listing them (names, time spans, keys: hrr-motion info), picking
one by name or index, and reading its translation / rotation / scale channels, each sampled at any
time by its interpolation (LINEAR, STEP or CUBICSPLINE). :mod:`.gltf` reads a skin's motion from
them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .gltf_file import GltfDocument
from .limits import MAX_BVH_VALUE
from .motion import FPS
from .rotations import quat_slerp

_PATH_WIDTHS = {"translation": 3, "rotation": 4, "scale": 3}
_INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
MIN_SCALE = 1e-6  # a scale key below this collapses the skeleton below it to a point


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
class AnimationChannel:
    """One animation channel, read: the node it keys, which property, key times and values."""

    node: int
    path: str  # translation / rotation / scale
    times: np.ndarray  # (K,) seconds
    values: np.ndarray  # (K, W), or (K, 3, W) for CUBICSPLINE (in-tangent, value, out-tangent)
    interpolation: str


def animation_names(doc: GltfDocument) -> list[str]:
    """The file's animations' names (``#index`` for one without a name)."""
    return [a.name or f"#{i}" for i, a in enumerate(doc.doc.animations or [])]


def pick_animation(doc: GltfDocument, animation: str | int | None) -> int:
    """The index of the animation asked for: by name first, then by index; the first by default."""
    names = animation_names(doc)
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


def read_channels(doc: GltfDocument, index: int) -> list[AnimationChannel]:
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
                f"animation {index} channel {c} ({target.path} of node {target.node}): {len(times)} key "
                f"times (must increase) for {values.shape[0]} values of width {values.shape[1]}"
            )
        where = f"animation {index} channel {c} ({target.path} of node {target.node})"
        _check_keys(doc, where, target.path, values[1::3] if per_key == 3 else values)
        if target.path == "rotation":
            values = values[:, [3, 0, 1, 2]]  # glTF quaternions are x, y, z, w
        if per_key == 3:
            values = values.reshape(len(times), 3, width)
        out.append(AnimationChannel(target.node, target.path, times, values, interpolation))
    return out


def _check_keys(doc: GltfDocument, where: str, path: str, keys: np.ndarray) -> None:
    """Keys (a cubic spline's values, not its tangents) that are no transform: a rotation far from
    a unit quaternion (of zeros, or scaled: the specification asks unit ones), a scale of zero (the
    skeleton below it collapses to a point) or a translation past the bound on file units a BVH
    is held to."""
    if path == "rotation":
        length = np.linalg.norm(keys, axis=-1)
        bad = np.flatnonzero(np.abs(length - 1.0) > 0.1)
        if len(bad):
            raise doc.fail(
                f"{where}: key {bad[0]} is no rotation (a quaternion of length {length[bad[0]]:.3g})"
            )
    elif path == "scale" and (np.abs(keys) < MIN_SCALE).any():
        raise doc.fail(f"{where}: a scale of zero collapses the skeleton below it")
    elif path == "translation" and not (np.abs(keys) <= MAX_BVH_VALUE).all():
        raise doc.fail(f"{where}: a key lies beyond {MAX_BVH_VALUE:g} file units of the origin")


def sample_channel(ch: AnimationChannel, times: np.ndarray) -> np.ndarray:
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
    channels = read_channels(doc, index)
    if not channels:
        return GltfAnimation(animation_names(doc)[index], index, 0.0, 0, 0)
    start = min(c.times[0] for c in channels)
    end = max(c.times[-1] for c in channels)
    return GltfAnimation(
        animation_names(doc)[index],
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
    index = pick_animation(doc, animation)
    return {
        "animation": animation_names(doc)[index],
        "animations": [_describe(doc, i).as_dict() for i in range(len(doc.doc.animations))],
    }
