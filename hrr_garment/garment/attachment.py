"""Attached vertices follow the body by linear blend skinning to their nearest bones.

Each attached vertex is bound, in the rest pose, to the joints of its two nearest capsules (by
signed distance), weighted by inverse squared distance; a waistband vertex between the pelvis and
the spine thus blends both, a strap vertex on the shoulder follows the collar. Only torso joints
are candidates: a strap that took 12 % of the upper arm's rotation stretched by 65 % when the arm
dropped from the T-pose, and a waistband must not follow a swinging thigh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, capsule_signed_distance
from ..body.mesh_distance import nearest_on_mesh
from ..body.skinned_body import SkinnedBody
from ..motion.skeleton import JOINT_INDEX, PARENTS
from .mesh import GarmentMesh

MAX_SKIN_JOINTS = 4  # joints an attached vertex bound to the skin follows (a glTF skin's own limit)
TORSO_JOINTS: tuple[str, ...] = ("pelvis", "spine1", "spine2", "spine3", "neck", "l_collar", "r_collar")


@dataclass(frozen=True)
class SkinBinding:
    """vertices (A,) garment indices; joints (A, K); weights (A, K) summing to 1; offsets (A, K, 3)
    rest-pose position relative to each joint (the rest pose has identity global rotations)."""

    vertices: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    offsets: np.ndarray

    def pose(self, global_rotations: np.ndarray, joint_positions: np.ndarray) -> np.ndarray:
        """(T, A, 3) attached vertex positions for FK results (T, 22, 3, 3) and (T, 22, 3)."""
        rot = global_rotations[:, self.joints]  # (T, A, K, 3, 3)
        pos = joint_positions[:, self.joints]  # (T, A, K, 3)
        per_joint = np.einsum("takij,akj->taki", rot, self.offsets) + pos
        return np.einsum("taki,ak->tai", per_joint, self.weights)


def bind_attached(
    mesh: GarmentMesh, body: BodyModel = DEFAULT_BODY, bones: int = 2, joints: tuple[str, ...] = TORSO_JOINTS
) -> SkinBinding:
    """Skin the mesh's attached vertices (rest pose) to the nearest capsules among ``joints``."""
    verts = mesh.vertices[mesh.attached].astype(np.float64)
    joints_rest = body.rest_joints()  # the body's own rest joints (the mannequin's by default)
    a, b = body.rest_pose()
    cap_joint = np.array([JOINT_INDEX[c.joint] for c in body.capsules])
    # Distance to every capsule, then the nearest capsule per distinct joint.
    dist = np.stack(
        [
            capsule_signed_distance(verts, a[c : c + 1], b[c : c + 1], radii=body.radii[c : c + 1])[0]
            for c in range(len(cap_joint))
        ],
        1,
    )
    per_joint = np.full((len(verts), len(PARENTS)), np.inf)
    allowed = {JOINT_INDEX[name] for name in joints}
    for c, j in enumerate(cap_joint):
        if j in allowed:
            per_joint[:, j] = np.minimum(per_joint[:, j], dist[:, c])
    nearest = np.argsort(per_joint, axis=1)[:, :bones]
    d = np.take_along_axis(per_joint, nearest, axis=1)
    w = 1.0 / np.maximum(d - d[:, :1] + 0.01, 1e-3) ** 2  # relative to the nearest: 1 cm softening
    w /= w.sum(1, keepdims=True)
    offsets = verts[:, None, :] - joints_rest[nearest]
    return SkinBinding(mesh.attached.copy(), nearest.astype(np.int64), w.astype(np.float64), offsets)


def bind_attached_to_skin(mesh: GarmentMesh, skin: SkinnedBody, body: BodyModel) -> SkinBinding:
    """Skin the mesh's attached vertices (rest pose) as the skin nearest to each is skinned: the
    weights of ``skin`` at its nearest point in ``body``'s rest pose, so that a strap or a waistband
    rides the body the viewer sees (a strap bound to the torso's capsules alone sank into the shoulder's
    skin, which follows the arm)."""
    from .visible_surface import rest_mesh

    verts = mesh.vertices[mesh.attached].astype(np.float64)
    _, face, bary = nearest_on_mesh(verts, rest_mesh(skin, body), skin.faces)
    weights = np.einsum("ak,akj->aj", bary, skin.weights[skin.faces[face]])  # (A, J)
    order = np.argsort(-weights, axis=1)[:, :MAX_SKIN_JOINTS]
    kept = np.take_along_axis(weights, order, 1)
    offsets = verts[:, None, :] - body.rest_joints()[order]
    return SkinBinding(
        mesh.attached.copy(), order.astype(np.int64), kept / kept.sum(1, keepdims=True), offsets
    )
