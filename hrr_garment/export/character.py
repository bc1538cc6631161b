"""The character's own skinned mesh in a GLB, posed by the clip the garment was animated on.

    character = skinned_character("hero.glb")                   # its mesh, weights and fitted body
    write_glb(read_animation_h5("out.h5"), "hero_dress.glb", character=character)

``hrr-animate --body hero.glb`` animates the garment on the character's fitted body; out.h5 keeps
the motion as that body played it (local joint rotations, the pelvis's path, the body's skeleton;
format 4). The export puts the character's mesh, as the file has it in its bind pose, on a
22-joint skeleton that plays that motion, so the garment and the body move together in any glTF
viewer or engine.

The mesh is re-skinned onto the canonical joints: each vertex keeps the file's weights, a joint
the canonical skeleton lacks (fingers, twist bones) giving its share to its nearest canonical
ancestor (:class:`~hrr_garment.body.character.Character`). The bind pose is the fitted body's
skeleton bent into the character's bind pose (:func:`~hrr_garment.body.fit.rest_pose_rotations`:
each bone turned onto the file's by the shortest arc), so the mesh at the bind pose is the file's
mesh exactly and every other frame is linear blend skinning from it. The export refuses an
animation made on another body (its skeleton differs from the character's fitted one) and an
out.h5 from before format 4.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..body.body_file import BodyRecord
from ..body.character import character_body
from ..body.fit import rest_pose_rotations
from ..body.symmetry import symmetrized_record
from ..data.animation_file import AnimationFile
from ..errors import InputError
from ..garment.mesh import vertex_normals
from ..motion.skeleton import JOINT_NAMES, PARENTS
from .glb_blob import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER

INFLUENCES = 4  # joints per vertex in the GLB (glTF's JOINTS_0 / WEIGHTS_0)
SKELETON_TOLERANCE_M = 1e-3  # how far the animation's bones may differ from the character's fitted ones


@dataclass(frozen=True)
class SkinnedCharacter:
    """A character's mesh in its bind pose (the project's frame), weighted to the canonical joints,
    and the fitted body whose skeleton poses it."""

    path: Path
    vertices: np.ndarray  # (V, 3) float64
    faces: np.ndarray  # (F, 3)
    weights: np.ndarray  # (V, 22)
    record: BodyRecord
    bind: np.ndarray  # (22, 4, 4) each canonical joint's world matrix in the bind pose

    @property
    def inverse_bind(self) -> np.ndarray:
        return np.linalg.inv(self.bind)


def skinned_character(path: str | Path, **read) -> SkinnedCharacter:
    """The character file ``path`` ready to export (``read``:
    :func:`~hrr_garment.body.character.read_character`'s options); an InputError naming the file
    where its mesh carries no skin weights."""
    record, character = character_body(path, **read)
    # the body a clip is played by (its left and right made alike where they nearly are), so that the
    # exported skeleton is the one out.h5's clip stands on
    record = symmetrized_record(record)
    if character.weights is None:
        raise InputError(path, "its skinned mesh has no JOINTS_0 / WEIGHTS_0, so it cannot be posed")
    rotations = rest_pose_rotations(record.skeleton, character.joints)  # global, T-pose -> bind pose
    positions = np.zeros((len(JOINT_NAMES), 3))
    positions[0] = character.joints[0]
    for j in range(1, len(JOINT_NAMES)):
        p = PARENTS[j]
        positions[j] = positions[p] + rotations[p] @ record.skeleton.offsets[j]
    bind = np.tile(np.eye(4), (len(JOINT_NAMES), 1, 1))
    bind[:, :3, :3], bind[:, :3, 3] = rotations, positions
    return SkinnedCharacter(Path(path), character.vertices, character.faces, character.weights, record, bind)


def top_influences(weights: np.ndarray, count: int = INFLUENCES) -> tuple[np.ndarray, np.ndarray]:
    """(V, count) joint indices (uint16) and weights (float32, summing to 1) of each vertex's
    ``count`` heaviest joints; a slot of weight 0 names joint 0, as glTF asks (its validator warns
    of a zero weight on any other joint)."""
    order = np.argsort(-weights, axis=1, kind="stable")[:, :count]
    kept = np.take_along_axis(weights, order, 1)
    kept = (kept / np.maximum(kept.sum(1, keepdims=True), 1e-12)).astype(np.float32)
    return np.where(kept > 0, order, 0).astype(np.uint16), kept


def check_played_on(anim: AnimationFile, character: SkinnedCharacter) -> None:
    """Refuse an animation that carries no skeleton, or was played on another body than the character's."""
    if anim.rotations is None:
        raise InputError(
            anim.path,
            "carries no skeleton motion (written before out.h5 format 4): animate it again "
            "with hrr-animate --body CHARACTER to export the character with it",
        )
    apart = float(np.abs(np.asarray(anim.offsets, np.float64) - character.record.skeleton.offsets).max())
    if apart > SKELETON_TOLERANCE_M:
        raise InputError(
            anim.path,
            f"was animated on another body than {character.path.name}'s (their bones differ "
            f"by up to {1000 * apart:.0f} mm): animate it with hrr-animate --body "
            f"{character.path.name}",
        )


def continuous(quaternions: np.ndarray) -> np.ndarray:
    """Quaternions (T, ..., 4) with each frame's sign chosen to agree with the frame before: q and
    -q are one rotation, and interpolation between keys must not take the long way round."""
    q = np.array(quaternions, np.float64)
    for t in range(1, len(q)):
        q[t] *= np.where((q[t] * q[t - 1]).sum(-1, keepdims=True) < 0, -1.0, 1.0)
    return q


def add_character(
    gl, blob, anim: AnimationFile, *, character: SkinnedCharacter, gltf_parts: dict, times: int
) -> list[int]:
    """The character's joint nodes (animated by ``anim``'s skeleton motion), its skinned mesh and
    its skin, appended to ``gltf_parts`` (nodes, meshes, materials, samplers, channels, skins);
    ``times``: the accessor of the frame times. Returns the scene's new root nodes (the skeleton's
    root and the skinned mesh's node, which glTF wants at the root: its own transform is unused)."""
    check_played_on(anim, character)
    nodes, meshes, materials = gltf_parts["nodes"], gltf_parts["meshes"], gltf_parts["materials"]
    samplers, channels, skins = gltf_parts["samplers"], gltf_parts["channels"], gltf_parts["skins"]
    first = len(nodes)
    rotations = continuous(anim.rotations).astype(np.float32)
    for j, name in enumerate(JOINT_NAMES):
        children = [first + c for c, p in enumerate(PARENTS) if p == j] or None
        translation = anim.root_translation[0] if j == 0 else anim.offsets[j]
        nodes.append(
            gl.Node(
                name=name,
                translation=np.asarray(translation, float).tolist(),
                rotation=rotations[0, j].astype(float).tolist(),
                children=children,
            )
        )
        keyed = (("rotation", rotations[:, j], "VEC4"),) + (
            (("translation", anim.root_translation, "VEC3"),) if j == 0 else ()
        )
        for path, values, kind in keyed:
            samplers.append(
                gl.AnimationSampler(
                    input=times,
                    output=blob.stored(np.asarray(values, np.float32), kind),
                    interpolation="LINEAR",
                )
            )
            channels.append(
                gl.AnimationChannel(
                    sampler=len(samplers) - 1, target=gl.AnimationChannelTarget(node=first + j, path=path)
                )
            )
    joints, weights = top_influences(character.weights)
    vertices = character.vertices.astype(np.float32)
    attributes = gl.Attributes(
        POSITION=blob.stored(vertices, "VEC3", ARRAY_BUFFER, bounds=True),
        NORMAL=blob.stored(
            vertex_normals(vertices[None], character.faces)[0].astype(np.float32), "VEC3", ARRAY_BUFFER
        ),
        JOINTS_0=blob.stored(joints, "VEC4", ARRAY_BUFFER),
        WEIGHTS_0=blob.stored(weights, "VEC4", ARRAY_BUFFER),
    )
    materials.append(
        gl.Material(
            name="character",
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[0.8, 0.76, 0.72, 1.0], metallicFactor=0.0, roughnessFactor=0.8
            ),
        )
    )
    meshes.append(
        gl.Mesh(
            name="character",
            primitives=[
                gl.Primitive(
                    attributes=attributes,
                    material=len(materials) - 1,
                    indices=blob.stored(
                        character.faces.astype(np.uint32).ravel(), "SCALAR", ELEMENT_ARRAY_BUFFER
                    ),
                )
            ],
        )
    )
    inverse = (
        np.swapaxes(character.inverse_bind, 1, 2).reshape(len(JOINT_NAMES), 16).astype(np.float32)
    )  # column-major
    skins.append(
        gl.Skin(
            name="character",
            joints=list(range(first, first + len(JOINT_NAMES))),
            skeleton=first,
            inverseBindMatrices=blob.stored(inverse, "MAT4"),
        )
    )
    nodes.append(gl.Node(name=character.path.stem, mesh=len(meshes) - 1, skin=len(skins) - 1))
    return [first, len(nodes) - 1]
