"""GLB (binary glTF 2.0) export: the garment as a morph-target animation, optionally the body.

The garment is one mesh whose base is frame 0 and which has one morph target per later keyframe
(the target holds that keyframe minus the base). Its weights are animated with LINEAR
interpolation: at keyframe k the weights are one-hot on k, so between two keyframes the mesh is
their linear interpolation, and keyframes (chosen by :mod:`.keyframes`) keep every frame within
the stated tolerance. glTF is Y up in metres, which is out.h5's convention, so no conversion.

Normals (unless ``normals=False``): the base carries frame 0's vertex normals and each target its
keyframe's normals minus them, so an engine that morphs normals (three.js, Blender, Unity) shades
the cloth smoothly; without them three.js shades every triangle flat. Renderers normalise the
blended normal, so between keyframes it is the normalised blend of the two keyframes' normals.
They add about as many bytes as the positions.

The body is a node per capsule (a rigid mesh) with animated translation and rotation, or, for a
character file, the character's own skinned mesh on a skeleton playing the clip (:mod:`.character`).
Needs the ``export`` extra (pygltflib).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..data.animation_file import AnimationFile
from ..garment.mesh import vertex_normals
from ..io_utils import atomic_write_bytes
from .character import SkinnedCharacter, add_character
from .keyframes import Keyframes, select_keyframes

_FLOAT, _UINT, _USHORT = 5126, 5125, 5123
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


def _gltf():
    try:
        import pygltflib
    except ImportError:
        raise ImportError("GLB export needs pygltflib: pip install 'hrr_garment[export]'") from None
    return pygltflib


class _Blob:
    """The GLB binary chunk under construction: buffer views and accessors appended in order."""

    def __init__(self, gl):
        self.gl, self.parts, self.size = gl, [], 0
        self.views: list = []
        self.accessors: list = []

    def view(self, array: np.ndarray, target: int | None = None, stride: int | None = None) -> int:
        """``stride`` is required by glTF when several vertex accessors share one view."""
        data = np.ascontiguousarray(array).tobytes()
        self.views.append(
            self.gl.BufferView(
                buffer=0, byteOffset=self.size, byteLength=len(data), target=target, byteStride=stride
            )
        )
        pad = (-len(data)) % 4
        self.parts.append(data + b"\0" * pad)
        self.size += len(data) + pad
        return len(self.views) - 1

    def accessor(self, view: int, array: np.ndarray, kind: str, bounds: bool = False, offset: int = 0) -> int:
        """An accessor over ``array`` (already stored in ``view`` at byte ``offset``)."""
        flat = array.reshape(len(array), -1)
        component = {np.dtype(np.uint32): _UINT, np.dtype(np.uint16): _USHORT}.get(array.dtype, _FLOAT)
        extra = {"min": flat.min(0).tolist(), "max": flat.max(0).tolist()} if bounds else {}
        self.accessors.append(
            self.gl.Accessor(
                bufferView=view,
                byteOffset=offset,
                componentType=component,
                count=len(array),
                type=kind,
                **extra,
            )
        )
        return len(self.accessors) - 1

    def stored(self, array: np.ndarray, kind: str, target: int | None = None, bounds: bool = False) -> int:
        return self.accessor(self.view(array, target), array, kind, bounds)

    def bytes(self) -> bytes:
        return b"".join(self.parts)


def _quaternion_z_to(d: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) rotating +Z onto unit directions d (T, 3), sign-continuous in T."""
    w = 1.0 + d[:, 2]
    q = np.concatenate([np.stack([-d[:, 1], d[:, 0], np.zeros(len(d))], 1), w[:, None]], 1)
    flip = w < 1e-8  # d = -Z: half turn about X
    q[flip] = (1.0, 0.0, 0.0, 0.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    sign = np.cumprod(np.where((q[1:] * q[:-1]).sum(1) < 0, -1.0, 1.0))  # slerp takes the short way
    q[1:] *= sign[:, None]
    return q


@dataclass(frozen=True)
class GlbReport:
    """What write_glb wrote: the path, the keyframes and the size."""

    path: Path
    keyframes: Keyframes
    bytes: int


def write_glb(
    anim: AnimationFile,
    path: str | Path,
    tolerance: float = 0.001,
    with_body: bool = False,
    normals: bool = True,
    character: SkinnedCharacter | None = None,
) -> GlbReport:
    """Write ``anim`` as GLB. ``tolerance`` (metres) bounds the keyframe reduction; 0 keeps every
    frame. ``normals``: vertex normals on the base and the targets (see the module docstring).
    ``with_body``: the collision capsules too; ``character``: the character's own skinned mesh,
    posed by the clip (:func:`.character.skinned_character`)."""
    gl = _gltf()
    path = Path(path)
    keys = select_keyframes(anim.vertices, tolerance)
    verts = anim.vertices.astype(np.float32)
    base = verts[0]
    deltas = verts[keys.frames[1:]] - base  # (K-1, V, 3)
    blob = _Blob(gl)
    position = blob.stored(base, "VEC3", _ARRAY_BUFFER, bounds=True)
    indices = blob.stored(anim.faces.astype(np.uint32).ravel(), "SCALAR", _ELEMENT_ARRAY_BUFFER)
    normal, normal_deltas = None, None
    if normals:
        keyframe_normals = vertex_normals(verts[keys.frames], anim.faces).astype(np.float32)  # (K, V, 3)
        normal = blob.stored(keyframe_normals[0], "VEC3", _ARRAY_BUFFER)
        normal_deltas = keyframe_normals[1:] - keyframe_normals[0]
    targets = []
    if len(deltas):
        view = blob.view(deltas, _ARRAY_BUFFER, stride=12)
        normal_view = None if normal_deltas is None else blob.view(normal_deltas, _ARRAY_BUFFER, stride=12)
        for k, delta in enumerate(deltas):
            target = {"POSITION": blob.accessor(view, delta, "VEC3", True, k * delta.nbytes)}
            if normal_view is not None:
                target["NORMAL"] = blob.accessor(
                    normal_view, normal_deltas[k], "VEC3", False, k * delta.nbytes
                )
            targets.append(gl.Attributes(**target))
    materials = [
        gl.Material(
            name="garment",
            doubleSided=True,
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[0.27, 0.43, 0.78, 1.0], metallicFactor=0.0, roughnessFactor=0.9
            ),
        )
    ]
    primitive = gl.Primitive(
        attributes=gl.Attributes(POSITION=position, NORMAL=normal),
        indices=indices,
        material=0,
        targets=targets or None,
    )
    names = [f"frame_{f:05d}" for f in keys.frames[1:]]
    meshes = [
        gl.Mesh(
            name=str(anim.attrs.get("garment", "garment")),
            primitives=[primitive],
            weights=[0.0] * len(targets) or None,
            extras={"targetNames": names} if names else None,
        )
    ]
    nodes = [gl.Node(name="garment", mesh=0)]
    samplers, channels = [], []
    if len(targets):
        times = (keys.frames / anim.fps).astype(np.float32)
        weights = np.zeros((len(keys.frames), len(targets)), np.float32)
        weights[np.arange(1, len(keys.frames)), np.arange(len(targets))] = 1.0
        samplers.append(
            gl.AnimationSampler(
                input=blob.stored(times, "SCALAR", bounds=True),
                output=blob.stored(weights.ravel(), "SCALAR"),
                interpolation="LINEAR",
            )
        )
        channels.append(
            gl.AnimationChannel(sampler=0, target=gl.AnimationChannelTarget(node=0, path="weights"))
        )
    scene_nodes, skins = [0], []
    if with_body:
        scene_nodes.append(_add_body(gl, anim, blob, nodes, meshes, materials, samplers, channels))
    if character is not None:
        times = blob.stored((np.arange(anim.num_frames) / anim.fps).astype(np.float32), "SCALAR", bounds=True)
        parts = {
            "nodes": nodes,
            "meshes": meshes,
            "materials": materials,
            "samplers": samplers,
            "channels": channels,
            "skins": skins,
        }
        scene_nodes.extend(add_character(gl, blob, anim, character=character, gltf_parts=parts, times=times))
    gltf = gl.GLTF2(
        asset=gl.Asset(generator="hrr_garment", version="2.0"),
        scene=0,
        # the clip's rate and length where an importer that reads scene extras (Blender's, into the
        # scene's custom properties) can set its timeline from them: glTF itself has only seconds
        scenes=[
            gl.Scene(
                name=str(anim.attrs.get("source_motion", "animation")),
                nodes=scene_nodes,
                extras={"fps": anim.fps, "frames": anim.num_frames},
            )
        ],
        nodes=nodes,
        meshes=meshes,
        materials=materials,
        skins=skins,
        accessors=blob.accessors,
        bufferViews=blob.views,
        buffers=[gl.Buffer(byteLength=blob.size)],
        animations=[gl.Animation(name="garment", samplers=samplers, channels=channels)] if channels else [],
        extras={"fps": anim.fps, "keyframe_tolerance_m": tolerance, "keyframe_max_error_m": keys.max_error},
    )
    gltf.set_binary_blob(blob.bytes())
    data = b"".join(gltf.save_to_bytes())
    atomic_write_bytes(path, data)
    return GlbReport(path, keys, len(data))


def _add_body(
    gl,
    anim: AnimationFile,
    blob: _Blob,
    nodes: list,
    meshes: list,
    materials: list,
    samplers: list,
    channels: list,
) -> int:
    """Capsule nodes under a "body" node; returns the body node's index."""
    from ..body.capsules import body_mesh

    anim.body_mesh(0)  # raises "no body in this file" for version-1 files
    caps = anim.capsules.astype(np.float64)
    materials.append(
        gl.Material(
            name="body",
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[0.8, 0.76, 0.72, 1.0], metallicFactor=0.0, roughnessFactor=0.8
            ),
        )
    )
    times = blob.stored((np.arange(anim.num_frames) / anim.fps).astype(np.float32), "SCALAR", bounds=True)
    children = []
    for c, radius in enumerate(anim.radii.astype(np.float64)):
        axis = caps[:, c, 1] - caps[:, c, 0]
        length = float(np.linalg.norm(axis, axis=1).mean())  # rigid: the same in every frame
        v, f = body_mesh(
            np.zeros((1, 3)), np.array([[0.0, 0.0, length]]), np.array([radius]), segments=12, rings=6
        )
        prim = gl.Primitive(
            attributes=gl.Attributes(
                POSITION=blob.stored(v.astype(np.float32), "VEC3", _ARRAY_BUFFER, bounds=True),
                NORMAL=blob.stored(vertex_normals(v, f).astype(np.float32), "VEC3", _ARRAY_BUFFER),
            ),  # else shaded faceted
            indices=blob.stored(f.astype(np.uint32).ravel(), "SCALAR", _ELEMENT_ARRAY_BUFFER),
            material=len(materials) - 1,
        )
        meshes.append(gl.Mesh(name=f"capsule_{c}", primitives=[prim]))
        direction = axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
        nodes.append(gl.Node(name=f"capsule_{c}", mesh=len(meshes) - 1))
        children.append(len(nodes) - 1)
        for key, values, kind in (
            ("translation", caps[:, c, 0], "VEC3"),
            ("rotation", _quaternion_z_to(direction), "VEC4"),
        ):
            samplers.append(
                gl.AnimationSampler(
                    input=times, output=blob.stored(values.astype(np.float32), kind), interpolation="LINEAR"
                )
            )
            channels.append(
                gl.AnimationChannel(
                    sampler=len(samplers) - 1, target=gl.AnimationChannelTarget(node=len(nodes) - 1, path=key)
                )
            )
    nodes.append(gl.Node(name="body", children=children))
    return len(nodes) - 1


def _accessor_array(gltf, blob: bytes, index: int) -> np.ndarray:
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
    dtype = {_UINT: np.uint32, _USHORT: np.uint16}.get(acc.componentType, np.float32)
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return np.frombuffer(blob, dtype, acc.count * width, start).reshape(acc.count, width)


def _morphed(path: str | Path, attribute: str) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The garment mesh's ``attribute`` (POSITION or NORMAL) at the animation's keyframes, base +
    sum of weighted targets: (times (K,), values (K, V, 3) or None without the attribute, faces)."""
    gl = _gltf()
    gltf = gl.GLTF2().load(str(path))
    blob = gltf.binary_blob()
    prim = gltf.meshes[gltf.nodes[0].mesh].primitives[0]
    faces = _accessor_array(gltf, blob, prim.indices).reshape(-1, 3)
    if getattr(prim.attributes, attribute) is None:
        return np.zeros(1), None, faces
    base = _accessor_array(gltf, blob, getattr(prim.attributes, attribute)).astype(np.float64)
    found = [
        t[attribute] if isinstance(t, dict) else getattr(t, attribute) for t in prim.targets or []
    ]  # dicts once loaded
    targets = (
        np.stack([_accessor_array(gltf, blob, i) for i in found]) if found else np.zeros((0,) + base.shape)
    )
    if not gltf.animations:
        return np.zeros(1), base[None], faces
    sampler = next(
        gltf.animations[0].samplers[ch.sampler]
        for ch in gltf.animations[0].channels
        if ch.target.path == "weights"
    )
    times = _accessor_array(gltf, blob, sampler.input)[:, 0]
    weights = _accessor_array(gltf, blob, sampler.output).reshape(len(times), len(targets)).astype(np.float64)
    return times, base + np.einsum("kt,tvc->kvc", weights, targets), faces


def read_glb_keyframes(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read back a GLB written by :func:`write_glb`: (keyframe times (K,), garment vertices at those
    times (K, V, 3) evaluated as base + sum of weighted targets, faces (F, 3))."""
    return _morphed(path, "POSITION")


def read_glb_normals(path: str | Path) -> np.ndarray | None:
    """The garment's normals at the keyframes as a renderer shades them (base + weighted targets,
    normalised), (K, V, 3); None when the file has none (``normals=False``)."""
    normals = _morphed(path, "NORMAL")[1]
    return None if normals is None else normals / np.linalg.norm(normals, axis=-1, keepdims=True)
