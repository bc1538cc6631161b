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

import json
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from ..errors import MotionError
from .bvh_motion import PLAUSIBLE_HEIGHT_M, detect_unit_scale
from .joint_maps import resolve_joint_map
from .limits import MAX_BVH_JOINTS, check_frame_budget
from .motion import FPS, Motion
from .retarget import SourceMotion, check_source, retarget, standing_height_from_legs
from .rotations import matrix_to_quat, quat_slerp, quat_to_matrix

GLTF_SUFFIXES = (".glb", ".gltf")
# componentType -> (little-endian dtype, divisor of a normalized integer)
_COMPONENTS = {5120: ("<i1", 127.0), 5121: ("<u1", 255.0), 5122: ("<i2", 32767.0), 5123: ("<u2", 65535.0),
               5125: ("<u4", None), 5126: ("<f4", None)}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_PATH_WIDTHS = {"translation": 3, "rotation": 4, "scale": 3}
_INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
# pygltflib's failures on a file that is not glTF (or is cut short): one line each, never a traceback
_READ_ERRORS = (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError, struct.error, UnicodeDecodeError)


def _pygltflib():
    try:
        import pygltflib
    except ImportError:
        raise ImportError("reading glTF / GLB motion needs pygltflib: pip install 'hrr_garment[export]'") from None
    return pygltflib


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
        return {"name": self.name, "index": self.index, "duration_s": round(self.duration_s, 4),
                "keyframes": self.keyframes, "frames_30fps": int(np.floor(self.duration_s * FPS + 1e-4)) + 1,
                "channels": self.channels}


@dataclass
class _Channel:
    """One animation channel, read: the node it keys, which property, key times and values."""

    node: int
    path: str  # translation / rotation / scale
    times: np.ndarray  # (K,) seconds
    values: np.ndarray  # (K, W), or (K, 3, W) for CUBICSPLINE (in-tangent, value, out-tangent)
    interpolation: str


class _Document:
    """A loaded glTF document and its buffers' bytes, with checked access to accessors."""

    def __init__(self, path: Path):
        self.path = path
        gltf = _pygltflib()
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise MotionError(path, f"cannot read file ({exc.strerror})") from None
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                doc = gltf.GLTF2.load_from_bytes(data) if data[:4] == b"glTF" else gltf.GLTF2.from_json(data.decode("utf-8"))
        except (*_READ_ERRORS, json.JSONDecodeError) as exc:
            raise MotionError(path, f"not a readable glTF 2.0 / GLB file, or cut short ({type(exc).__name__}: {exc})") from None
        if doc is None or not isinstance(doc.nodes, list):
            raise MotionError(path, "not a readable glTF 2.0 / GLB file (no JSON chunk)")
        if "EXT_meshopt_compression" in (doc.extensionsRequired or []):
            raise MotionError(path, "its data is compressed with EXT_meshopt_compression, which pygltflib does not "
                                    "decode; export it without compression")
        self.doc = doc
        self._buffers: dict[int, bytes] = {}

    def fail(self, problem: str) -> MotionError:
        """A :class:`MotionError` naming this file."""
        return MotionError(self.path, problem)

    def _buffer(self, index: int) -> bytes:
        if index not in self._buffers:
            buf = self.doc.buffers[index]
            uri = buf.uri
            try:
                if uri is None:
                    data = self.doc.binary_blob()
                elif uri.startswith("data:"):
                    data = self.doc.decode_data_uri(uri)
                else:
                    data = self._external(unquote(uri), buf.byteLength or 0)
            except _READ_ERRORS as exc:
                raise self.fail(f"cannot read buffer {index} ({uri or 'the GLB binary chunk'}: {exc})") from None
            if data is None or len(data) < (buf.byteLength or 0):
                held = 0 if data is None else len(data)
                raise self.fail(f"buffer {index} declares {buf.byteLength} bytes but the file holds {held}: "
                                "the file is cut short")
            self._buffers[index] = bytes(data)
        return self._buffers[index]

    def _external(self, uri: str, size: int) -> bytes:
        """The first ``size`` bytes of a buffer file beside a .gltf (never a path out of its folder)."""
        relative = Path(uri)
        target = self.path.parent / relative
        if relative.is_absolute() or ".." in relative.parts or not target.is_file():
            raise self.fail(f"buffer file {uri!r} is not a file beside the .gltf")
        with open(target, "rb") as fh:
            return fh.read(size)

    def accessor(self, index: int, raw_integers: bool = False) -> np.ndarray:
        """Accessor ``index`` as (count, width) float64, normalized integers scaled to [-1, 1].
        ``raw_integers``: integers not flagged ``normalized`` are kept as they are (indices, joint
        numbers, quantized positions) instead of scaled as animation outputs' integers are."""
        try:
            acc = self.doc.accessors[index]
            view = self.doc.bufferViews[acc.bufferView] if acc.bufferView is not None else None
            dtype, divisor = _COMPONENTS[acc.componentType]
            width = _WIDTHS[acc.type]
        except (IndexError, KeyError, TypeError):
            raise self.fail(f"accessor {index} is missing or of an unknown type") from None
        if acc.sparse is not None:
            raise self.fail(f"accessor {index} is sparse, which this reader does not support")
        if view is None:
            return np.zeros((acc.count, width))  # the spec: an accessor without a buffer view holds zeros
        data = self._buffer(view.buffer)
        item = np.dtype(dtype).itemsize
        stride = view.byteStride or item * width
        start, end = (view.byteOffset or 0) + (acc.byteOffset or 0), (view.byteOffset or 0) + view.byteLength
        needed = stride * (acc.count - 1) + item * width if acc.count else 0
        if acc.count < 0 or start + needed > min(end, len(data)):
            raise self.fail(f"accessor {index} reaches past the end of its buffer: the file is cut short or corrupt")
        values = np.ndarray((acc.count, width), dtype=dtype, buffer=data, offset=start, strides=(stride, item)).astype(np.float64)
        if divisor is not None and (acc.normalized or (dtype != "<u4" and not raw_integers)):
            values = np.maximum(values / divisor, -1.0)
        if not np.isfinite(values).all():
            raise self.fail(f"accessor {index} holds non-finite values (NaN or inf)")
        return values


# --- the node tree ---------------------------------------------------------------------------------


def _node_parents(doc: _Document) -> list[int]:
    """Each node's parent (-1 for roots); a node with two parents or a cycle is refused."""
    nodes = doc.doc.nodes
    parents = [-1] * len(nodes)
    for i, node in enumerate(nodes):
        for child in node.children or []:
            if not (0 <= child < len(nodes)) or parents[child] != -1 or child == i:
                raise doc.fail(f"node {i} lists child {child}, which is missing or already has a parent")
            parents[child] = i
    rooted = [False] * len(nodes)  # known to lead up to a root
    for i in range(len(nodes)):
        path, k = set(), i
        while k >= 0 and not rooted[k]:
            if k in path:
                raise doc.fail(f"the node tree has a cycle through node {k}")
            path.add(k)
            k = parents[k]
        for k in path:
            rooted[k] = True
    return parents


def _rest_trs(node) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A node's own translation, rotation (w, x, y, z) and scale; a ``matrix`` is decomposed."""
    if node.matrix is not None and not np.allclose(node.matrix, np.eye(4).ravel()):
        m = np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T  # glTF matrices are column-major
        scale = np.linalg.norm(m[:3, :3], axis=0)
        if np.linalg.det(m[:3, :3]) < 0:
            scale[0] = -scale[0]
        rot = m[:3, :3] / np.where(scale == 0, 1.0, scale)
        return m[:3, 3], matrix_to_quat(rot), scale
    t = np.asarray(node.translation if node.translation is not None else (0.0, 0.0, 0.0), dtype=np.float64)
    q = np.asarray(node.rotation if node.rotation is not None else (0.0, 0.0, 0.0, 1.0), dtype=np.float64)[[3, 0, 1, 2]]
    s = np.asarray(node.scale if node.scale is not None else (1.0, 1.0, 1.0), dtype=np.float64)
    return t, q, s


def _chain(parents: list[int], nodes: list[int]) -> list[int]:
    """``nodes`` and all their ancestors, each after its parent."""
    order: list[int] = []
    seen: set[int] = set()
    for n in nodes:
        path = []
        while n >= 0 and n not in seen:
            path.append(n)
            seen.add(n)
            n = parents[n]
        order.extend(reversed(path))
    return order


def _world(order: list[int], parents: list[int], local: dict[int, tuple]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """World (linear part (F, 3, 3), translation (F, 3)) of each node in ``order`` from its local
    (translation (F, 3), rotation (F, 4), scale (F, 3))."""
    world: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for n in order:
        t, q, s = local[n]
        linear = quat_to_matrix(q) * s[..., None, :]
        if parents[n] in world:
            p_lin, p_t = world[parents[n]]
            linear, t = p_lin @ linear, p_t + (p_lin @ t[..., None])[..., 0]
        world[n] = (linear, t)
    return world


def open_gltf(path: str | Path) -> _Document:
    """A glTF / GLB file loaded with its buffers (accessors read by ``.accessor(i)``, the pygltflib
    document as ``.doc``); a file that cannot be read raises :class:`MotionError` naming it."""
    return _Document(Path(path))


def rest_world_matrices(doc: _Document) -> np.ndarray:
    """(N, 4, 4) every node's world matrix in its rest transforms, through the whole node tree."""
    parents = _node_parents(doc)
    world = _rest_world(doc, _chain(parents, list(range(len(parents)))), parents)
    out = np.tile(np.eye(4), (len(parents), 1, 1))
    for n, (linear, t) in world.items():
        out[n, :3, :3], out[n, :3, 3] = linear[0], t[0]
    return out


def _rotation_part(linear: np.ndarray) -> np.ndarray:
    """The rotation of a world transform's linear part, its scale removed (polar decomposition)."""
    u, _, vt = np.linalg.svd(linear)
    d = np.sign(np.linalg.det(u @ vt))
    u[..., :, 2] *= d[..., None]
    return u @ vt


# --- animations ------------------------------------------------------------------------------------


def _animation_names(doc: _Document) -> list[str]:
    return [a.name or f"#{i}" for i, a in enumerate(doc.doc.animations or [])]


def _pick_animation(doc: _Document, animation: str | int | None) -> int:
    """The index of the animation asked for: by name first, then by index; the first by default."""
    names = _animation_names(doc)
    if not names:
        raise doc.fail("the file has no animations (a glTF motion is read from an animation of a skinned character)")
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


def _channels(doc: _Document, index: int) -> list[_Channel]:
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
            raise doc.fail(f"animation {index} channel {c} names sampler {channel.sampler}, which is missing") from None
        interpolation = sampler.interpolation or "LINEAR"
        if interpolation not in _INTERPOLATIONS:
            raise doc.fail(f"animation {index} channel {c}: unknown interpolation {interpolation!r}")
        times = doc.accessor(sampler.input)[:, 0]
        values = doc.accessor(sampler.output)
        width = _PATH_WIDTHS[target.path]
        per_key = 3 if interpolation == "CUBICSPLINE" else 1
        if len(times) == 0 or values.shape != (len(times) * per_key, width) or not (np.diff(times) >= 0).all():
            raise doc.fail(f"animation {index} channel {c} ({target.path} of node {target.node}): "
                           f"{len(times)} key times (must increase) for {values.shape[0]} values of width {values.shape[1]}")
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
        out = ((2 * u**3 - 3 * u**2 + 1) * v0 + (u**3 - 2 * u**2 + u) * d * b0
               + (-2 * u**3 + 3 * u**2) * v1 + (u**3 - u**2) * d * a1)
        return out / np.linalg.norm(out, axis=-1, keepdims=True) if ch.path == "rotation" else out
    v0, v1 = ch.values[i], ch.values[i + 1]
    if ch.path == "rotation":
        return quat_slerp(v0, v1, u[:, 0])
    return (1.0 - u) * v0 + u * v1


def _describe(doc: _Document, index: int) -> GltfAnimation:
    channels = _channels(doc, index)
    if not channels:
        return GltfAnimation(_animation_names(doc)[index], index, 0.0, 0, 0)
    start = min(c.times[0] for c in channels)
    end = max(c.times[-1] for c in channels)
    return GltfAnimation(_animation_names(doc)[index], index, float(end - start), max(len(c.times) for c in channels),
                         len(channels))


def gltf_animations(path: str | Path) -> list[GltfAnimation]:
    """The animations of a glTF / GLB file: names, durations, key counts (hrr-motion info)."""
    doc = _Document(Path(path))
    return [_describe(doc, i) for i in range(len(doc.doc.animations or []))]


def gltf_summary(path: str | Path, animation: str | int | None = None) -> dict:
    """The animation :func:`load_gltf` reads for ``animation`` and all of the file's animations."""
    doc = _Document(Path(path))
    index = _pick_animation(doc, animation)
    return {"animation": _animation_names(doc)[index],
            "animations": [_describe(doc, i).as_dict() for i in range(len(doc.doc.animations))]}


# --- the skin and its motion -------------------------------------------------------------------------


def _pick_skin(doc: _Document, channels: list[_Channel]) -> list[int]:
    """The joints (node indices) of the skin the channels animate most (the first of equals)."""
    skins = doc.doc.skins or []
    if not skins:
        raise doc.fail("the file has no skin: motion is read from a skinned character's joints "
                       "(animated nodes without a skin are not read)")
    keyed = {c.node for c in channels}
    best = max(range(len(skins)), key=lambda s: (len(keyed & set(skins[s].joints or [])), -s))
    joints = list(skins[best].joints or [])
    if len(joints) > MAX_BVH_JOINTS:
        raise doc.fail(f"skin {best} has {len(joints)} joints, more than {MAX_BVH_JOINTS} (a human rig has under a few hundred)")
    if not joints or not all(isinstance(j, int) and 0 <= j < len(doc.doc.nodes) for j in joints):
        raise doc.fail(f"skin {best} has no joints or names nodes that are missing")
    if not keyed & set(joints):
        raise doc.fail(f"the animation keys none of skin {best}'s {len(joints)} joints")
    return joints


def _times(doc: _Document, channels: list[_Channel], fps: float) -> np.ndarray:
    """The output frame times: the animation's span at ``fps`` (its last partial frame left out, as
    other inputs are resampled)."""
    start = min(c.times[0] for c in channels)
    end = max(c.times[-1] for c in channels)
    frames = int(np.floor((end - start) * fps + 1e-4)) + 1
    check_frame_budget(doc.path, frames, fps, fps_out=fps)
    return start + np.arange(frames) / fps


def _local_transforms(doc: _Document, order: list[int], channels: list[_Channel], times: np.ndarray) -> dict[int, tuple]:
    """Each node's local (translation, rotation, scale) per frame: its channels where keyed, its
    rest transform elsewhere."""
    frames = len(times)
    local = {}
    for n in order:
        t, q, s = _rest_trs(doc.doc.nodes[n])
        local[n] = {"translation": np.broadcast_to(t, (frames, 3)), "rotation": np.broadcast_to(q, (frames, 4)),
                    "scale": np.broadcast_to(s, (frames, 3))}
    for ch in channels:
        if ch.node in local:
            local[ch.node][ch.path] = _sample(ch, times)
    return {n: (v["translation"], v["rotation"], v["scale"]) for n, v in local.items()}


def _rest_world(doc: _Document, order: list[int], parents: list[int]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    rest = {}
    for n in order:
        t, q, s = _rest_trs(doc.doc.nodes[n])
        rest[n] = (t[None], q[None], s[None])
    return _world(order, parents, rest)


@dataclass(frozen=True)
class GltfOptions:
    """How :func:`gltf_source` reads a file: which animation (name or index; None: the first),
    metres per file unit (None: the file's own metres, detected when implausible), a user joint map,
    the output frame rate."""

    animation: str | int | None = None
    unit_scale: float | None = None
    joint_map: dict | None = None
    fps: float = FPS


def gltf_source(path: str | Path, options: GltfOptions = GltfOptions()) -> tuple[SourceMotion, str, dict[str, int], str]:
    """A glTF / GLB animation on its own skeleton, in metres, at ``options.fps``: (the motion, the
    naming scheme, canonical joint name -> source joint index, the animation's name)."""
    doc = _Document(Path(path))
    index = _pick_animation(doc, options.animation)
    channels = _channels(doc, index)
    joints = _pick_skin(doc, channels)
    parents = _node_parents(doc)
    names = [doc.doc.nodes[j].name or f"node_{j}" for j in joints]
    joint_parents = []
    for j in joints:
        p = parents[j]
        while p >= 0 and p not in joints:
            p = parents[p]
        joint_parents.append(joints.index(p) if p >= 0 else -1)
    scheme, mapping = resolve_joint_map(names, str(doc.path), options.joint_map)
    order = _chain(parents, joints)
    times = _times(doc, channels, options.fps)
    world = _world(order, parents, _local_transforms(doc, order, channels, times))
    rest_world = _rest_world(doc, order, parents)
    rest = np.stack([rest_world[j][1][0] for j in joints])
    scale = _unit_scale(doc, options.unit_scale, rest, mapping)
    rest_rot = np.stack([_rotation_part(rest_world[j][0][0]) for j in joints])
    g_rot = np.stack([_rotation_part(world[j][0]) for j in joints], 1) @ np.swapaxes(rest_rot, -1, -2)
    g_pos = np.stack([world[j][1] for j in joints], 1) * scale
    src = SourceMotion(names, joint_parents, rest * scale, global_rotations=g_rot, global_positions=g_pos,
                       fps=options.fps, path=str(doc.path))
    check_source(src)
    return src, scheme, mapping, _animation_names(doc)[index]


def _unit_scale(doc: _Document, unit_scale: float | None, rest: np.ndarray, mapping: dict[str, int]) -> float:
    """Metres per unit of the composed world positions: 1 (glTF is metres) unless the standing
    height says otherwise (a file written in centimetres without a scaling node) or one is given."""
    if unit_scale is not None:
        if not (np.isfinite(unit_scale) and unit_scale > 0):
            raise doc.fail(f"unit scale must be a positive number of metres per file unit, got {unit_scale}")
        return float(unit_scale)
    lo, hi = PLAUSIBLE_HEIGHT_M
    if lo <= standing_height_from_legs(rest, mapping) <= hi:
        return 1.0
    return detect_unit_scale(rest, mapping, doc.path)


def load_gltf(path: str | Path, options: GltfOptions = GltfOptions(), ground: bool = True) -> Motion:
    """A glTF / GLB animation as canonical motion: retargeted, grounded, at ``options.fps``."""
    src, scheme, mapping, _ = gltf_source(path, options)
    local, root = retarget(src, mapping, ground=ground)
    return Motion(local, root, options.fps, source=str(path), source_skeleton=scheme,
                  source_height_m=standing_height_from_legs(src.rest_positions, mapping))
