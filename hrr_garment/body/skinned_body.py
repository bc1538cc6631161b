"""The body the viewer sees: a body's rest mesh skinned to the canonical joints, posed by linear blend
skinning as a game poses its character.

    visible = visible_body(record)     # a character's (its record's mesh), an anny body's, or None
    visible = character_skinned_body(character, skeleton)  # a fitted character's, from its file
    posed = visible.pose(motion.global_rotations, motion.joint_positions)   # (T, V, 3)

A vertex ``v`` with weights ``w_j`` is drawn at ``sum_j w_j (p_j + R_j R0_j^T (v - p0_j))``: ``R_j, p_j``
its joints' global rotations and positions in the motion, ``R0_j, p0_j`` the same in the mesh's rest
pose, found by bending the body's skeleton from its T-pose onto the mesh's joints
(:func:`rest_frames`), so a motion of the same skeleton at that pose gives the rest mesh back. The
weights are the mesh's own, gathered onto the 22 canonical joints (a bone the canonical skeleton
lacks, a finger or a twist bone, gives its weight to its nearest canonical ancestor): a character's
from its glTF skin (:func:`~.skinned_mesh.canonical_weights`), an anny body's from anny's rig
(:func:`anny_weights`). The rigid pieces the simulator can move are :mod:`.mesh_collider`'s; the
collider that follows this mesh is :mod:`.skin_collider`'s (:mod:`.bone_sdf`'s grids came first).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..motion.skeleton import JOINT_INDEX, PARENTS, Skeleton, forward_kinematics, global_to_local
from .capsules import BodyModel
from .fit import rest_pose_rotations
from .skinned_mesh import canonical_owners, gather_weights


def rest_frames(skeleton: Skeleton, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(22, 3, 3) global rotations and (22, 3) positions of ``skeleton`` bent from its T-pose onto a
    mesh's canonical ``joints`` (22, 3), as a motion of that skeleton would pose them."""
    joints = np.asarray(joints, np.float64)
    local = global_to_local(rest_pose_rotations(skeleton, joints)[None], PARENTS)
    g_rot, g_pos = forward_kinematics(
        local, joints[None, 0], skeleton.offsets.astype(np.float64), parents=PARENTS
    )
    return g_rot[0], g_pos[0]


@dataclass(frozen=True)
class SkinnedBody:
    """A rest mesh with linear-blend-skinning weights on J joints (22 for a body; any J works)."""

    vertices: np.ndarray  # (V, 3) float64, the rest mesh
    faces: np.ndarray  # (F, 3) int64
    weights: np.ndarray  # (V, J) float64, each row summing to 1
    rest_rotations: np.ndarray  # (J, 3, 3) the joints' global rotations in the rest pose
    rest_positions: np.ndarray  # (J, 3)

    def __post_init__(self) -> None:
        v, j = len(self.vertices), len(self.rest_positions)
        if self.weights.shape != (v, j) or self.rest_rotations.shape != (j, 3, 3):
            raise ValueError(
                f"a skinned body needs (V, J) weights and (J, 3, 3) rest rotations for its {v} "
                f"vertices and {j} joints, got {self.weights.shape} and {self.rest_rotations.shape}"
            )
        if not np.allclose(self.weights.sum(1), 1.0, atol=1e-4) or (self.weights < -1e-6).any():
            raise ValueError("a skinned body's weights must be non-negative and sum to 1 at each vertex")

    def joint_transforms(
        self, global_rotations: np.ndarray, joint_positions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each joint's rigid move from the rest pose, ``x -> R x + t``: (T, J, 3, 3) and (T, J, 3)."""
        rot = np.asarray(global_rotations, np.float64) @ np.swapaxes(self.rest_rotations, -1, -2)
        return rot, np.asarray(joint_positions, np.float64) - np.einsum(
            "tjab,jb->tja", rot, self.rest_positions
        )

    def pose(self, global_rotations: np.ndarray, joint_positions: np.ndarray) -> np.ndarray:
        """(T, V, 3) the skinned mesh for FK results (T, J, 3, 3) and (T, J, 3)."""
        rot, trans = self.joint_transforms(global_rotations, joint_positions)
        blended = np.einsum("vj,tjab->tvab", self.weights, rot)  # (T, V, 3, 3): linear, not rigid
        return np.einsum("tvab,vb->tva", blended, self.vertices) + np.einsum(
            "vj,tja->tva", self.weights, trans
        )


def skinned_body(skeleton: Skeleton, rest, weights: np.ndarray) -> SkinnedBody:
    """The skinned body of a ``rest`` mesh (anything with ``vertices``, ``faces`` and canonical
    ``joints`` in the same pose: a :class:`~.parametric.RestMesh`, a :class:`~.character.Character`)
    with its (V, 22) canonical ``weights``, posed by the motions of ``skeleton`` (fitted to it)."""
    rot, pos = rest_frames(skeleton, rest.joints)
    weights = np.asarray(weights, np.float64)  # stored as float32: summing to 1 again in float64
    return SkinnedBody(
        np.asarray(rest.vertices, np.float64),
        np.asarray(rest.faces, np.int64),
        weights / weights.sum(1, keepdims=True),
        rot,
        pos,
    )


def character_skinned_body(character, skeleton: Skeleton) -> SkinnedBody:
    """A :class:`~.character.Character`'s own skinned mesh (its file's weights), or a ValueError
    where its mesh carries no skin weights."""
    if character.weights is None:
        raise ValueError("the character's mesh carries no skin weights (JOINTS_0 / WEIGHTS_0)")
    return skinned_body(skeleton, character, character.weights)


@lru_cache(maxsize=1)
def anny_weights() -> np.ndarray:
    """(V, 22) anny's skin weights (of :data:`~.parametric.TOPOLOGY` on its Mixamo rig) gathered
    onto the canonical joints; the same for every shape."""
    from ..motion.joint_maps import resolve_joint_map
    from .parametric import _anny_model

    model = _anny_model()
    _, mapping = resolve_joint_map(list(model.bone_labels), "anny")
    parents = [int(p) for p in model.bone_parents]
    owner = canonical_owners(
        list(range(len(parents))), parents, {bone: JOINT_INDEX[c] for c, bone in mapping.items()}
    )
    bones = model.vertex_bone_indices.numpy().astype(np.int64)
    return gather_weights(bones, model.vertex_bone_weights.double().numpy(), owner)


def visible_body(record) -> SkinnedBody | None:
    """The mesh a viewer sees of a body (a :class:`~.body_file.BodyRecord`): a fitted character's
    own skinned mesh, which its record carries (body.json's ``mesh``); an anny body's, its
    parametric shape's rest mesh skinned by anny's weights; None for a body with neither (the
    mannequin) or an anny body where anny (the ``bodies`` extra) is not installed."""
    if record.mesh is not None:
        return _own_visible_body(record.mesh, record.body)
    if not record.shape:
        return None
    try:
        return _visible_body(tuple(sorted(record.shape.items())), record.body)
    except ImportError:
        return None


@lru_cache(maxsize=8)  # a character's mesh is large: a few bodies at a time
def _own_visible_body(mesh, body: BodyModel) -> SkinnedBody:
    # keyed by the mesh and the capsules (both hashed by identity), whose skeleton is fitted to the mesh
    return skinned_body(body.skeleton, mesh, mesh.weights)


@lru_cache(maxsize=32)
def _visible_body(shape: tuple, body: BodyModel) -> SkinnedBody:
    from .parametric import BodyShape, anny_rest_mesh

    # keyed by the capsules (hashed by identity), whose skeleton is the one fitted to the shape
    return skinned_body(body.skeleton, anny_rest_mesh(BodyShape(**dict(shape))), anny_weights())
