"""The collision capsules in a GLB: one rigid capsule mesh per capsule, its node's translation and
rotation animated to follow the capsule, all under a "body" node."""

from __future__ import annotations

import numpy as np

from ..data.animation_file import AnimationFile
from ..garment.mesh import vertex_normals
from .glb_blob import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, GlbBlob


def quaternion_z_to(d: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) rotating +Z onto unit directions d (T, 3), sign-continuous in T."""
    w = 1.0 + d[:, 2]
    q = np.concatenate([np.stack([-d[:, 1], d[:, 0], np.zeros(len(d))], 1), w[:, None]], 1)
    flip = w < 1e-8  # d = -Z: half turn about X
    q[flip] = (1.0, 0.0, 0.0, 0.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    sign = np.cumprod(np.where((q[1:] * q[:-1]).sum(1) < 0, -1.0, 1.0))  # slerp takes the short way
    q[1:] *= sign[:, None]
    return q


def add_capsule_body(gl, blob: GlbBlob, anim: AnimationFile, *, gltf_parts: dict) -> int:
    """Capsule nodes under a "body" node, appended to ``gltf_parts``' nodes, meshes, materials,
    samplers and channels; returns the body node's index."""
    nodes, meshes, materials = gltf_parts["nodes"], gltf_parts["meshes"], gltf_parts["materials"]
    samplers, channels = gltf_parts["samplers"], gltf_parts["channels"]
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
                POSITION=blob.stored(v.astype(np.float32), "VEC3", ARRAY_BUFFER, bounds=True),
                NORMAL=blob.stored(vertex_normals(v, f).astype(np.float32), "VEC3", ARRAY_BUFFER),
            ),  # else shaded faceted
            indices=blob.stored(f.astype(np.uint32).ravel(), "SCALAR", ELEMENT_ARRAY_BUFFER),
            material=len(materials) - 1,
        )
        meshes.append(gl.Mesh(name=f"capsule_{c}", primitives=[prim]))
        direction = axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
        nodes.append(gl.Node(name=f"capsule_{c}", mesh=len(meshes) - 1))
        children.append(len(nodes) - 1)
        for key, values, kind in (
            ("translation", caps[:, c, 0], "VEC3"),
            ("rotation", quaternion_z_to(direction), "VEC4"),
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
