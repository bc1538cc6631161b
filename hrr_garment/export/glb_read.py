"""Reading a GLB that :func:`~.glb.write_glb` wrote back: the garment's positions and normals at
its keyframes, evaluated as base + weighted morph targets, and its faces (the tests' and the
fuzzer's check of what an engine plays)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

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
