"""Reading a GLB that :func:`~.glb.write_glb` wrote back: the garment's positions and normals at
its keyframes, evaluated as base + weighted morph targets, and its faces; and a character's skinned
mesh at every frame, skinned as glTF says (the tests' and the fuzzer's check of what an engine plays,
and ``tools/render_glb.py``'s frames)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..motion.rotations import quat_to_matrix
from ..motion.skeleton import PARENTS
from .glb_blob import UINT, USHORT, pygltflib_module


def accessor_array(gltf, blob: bytes, index: int) -> np.ndarray:
    """Accessor ``index`` of a loaded GLB over its binary chunk ``blob``, as (count, width)."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
    dtype = {UINT: np.uint32, USHORT: np.uint16}.get(acc.componentType, np.float32)
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    return np.frombuffer(blob, dtype, acc.count * width, start).reshape(acc.count, width)


def _morphed(path: str | Path, attribute: str) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The garment mesh's ``attribute`` (POSITION or NORMAL) at the animation's keyframes, base +
    sum of weighted targets: (times (K,), values (K, V, 3) or None without the attribute, faces)."""
    gl = pygltflib_module()
    gltf = gl.GLTF2().load(str(path))
    blob = gltf.binary_blob()
    prim = gltf.meshes[gltf.nodes[0].mesh].primitives[0]
    faces = accessor_array(gltf, blob, prim.indices).reshape(-1, 3)
    if getattr(prim.attributes, attribute) is None:
        return np.zeros(1), None, faces
    base = accessor_array(gltf, blob, getattr(prim.attributes, attribute)).astype(np.float64)
    found = [
        t[attribute] if isinstance(t, dict) else getattr(t, attribute) for t in prim.targets or []
    ]  # dicts once loaded
    targets = (
        np.stack([accessor_array(gltf, blob, i) for i in found]) if found else np.zeros((0,) + base.shape)
    )
    if not gltf.animations:
        return np.zeros(1), base[None], faces
    sampler = next(
        gltf.animations[0].samplers[ch.sampler]
        for ch in gltf.animations[0].channels
        if ch.target.path == "weights"
    )
    times = accessor_array(gltf, blob, sampler.input)[:, 0]
    weights = accessor_array(gltf, blob, sampler.output).reshape(len(times), len(targets)).astype(np.float64)
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


def read_glb_character(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The character of a GLB written with ``character=`` (``hrr-export --character``), each frame
    skinned as glTF says: its joints' world matrices from the animation's keys, times the inverse
    bind matrices, blended by the weights. Returns the joints' world positions (T, 22, 3), the mesh
    (T, V, 3) and its faces (F, 3); None for a GLB without a skinned mesh."""
    gl = pygltflib_module()
    gltf = gl.GLTF2().load(str(path))
    skinned_nodes = [n for n in gltf.nodes if n.skin is not None and n.mesh is not None]
    if not skinned_nodes or not gltf.animations:
        return None
    blob = gltf.binary_blob()
    skin = gltf.skins[skinned_nodes[0].skin]
    read = lambda i: accessor_array(gltf, blob, i)  # noqa: E731
    keys = {
        (c.target.node, c.target.path): read(gltf.animations[0].samplers[c.sampler].output)
        for c in gltf.animations[0].channels
    }
    prim = gltf.meshes[skinned_nodes[0].mesh].primitives[0]
    vertices = read(prim.attributes.POSITION).astype(np.float64)
    joints, weights = read(prim.attributes.JOINTS_0).astype(np.int64), read(prim.attributes.WEIGHTS_0)
    faces = read(prim.indices).reshape(-1, 3).astype(np.int64)
    inverse = np.swapaxes(read(skin.inverseBindMatrices).reshape(-1, 4, 4), 1, 2)  # column-major
    world_joints, skinned = [], []
    for t in range(len(keys[(skin.joints[0], "rotation")])):
        world = np.zeros((len(skin.joints), 4, 4))
        for j, node in enumerate(skin.joints):
            local = np.eye(4)
            q = keys[(node, "rotation")][t]  # glTF's (x, y, z, w)
            local[:3, :3] = quat_to_matrix(np.array([q[3], q[0], q[1], q[2]], np.float64))
            moved = (node, "translation") in keys
            local[:3, 3] = keys[(node, "translation")][t] if moved else gltf.nodes[node].translation
            world[j] = local if PARENTS[j] < 0 else world[PARENTS[j]] @ local
        blend = np.einsum("vk,vkij->vij", weights, (world @ inverse)[joints])
        skinned.append(np.einsum("vij,vj->vi", blend[:, :3, :3], vertices) + blend[:, :3, 3])
        world_joints.append(world[:, :3, 3])
    return np.stack(world_joints), np.stack(skinned), faces
