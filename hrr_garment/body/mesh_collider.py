"""A body's own mesh as the simulator's collider: its rest mesh cut into rigid pieces, one per capsule.

    mesh = body_mesh(fitted.body, rest.vertices, rest.faces, rest.joints)   # a mesh in its rest pose
    posed = mesh.pose(motion.global_rotations, motion.joint_positions)       # (T, V, 3): the visible body

Each vertex rides rigidly with the joint of the capsule nearest to it in the rest pose (the
capsules posed like the mesh, as :func:`~.fit.fit_body` poses them). That is skinning with one bone
per vertex: exact along a bone, and where two pieces meet at a bending joint they overlap on the
inside of the bend and open a crack on the outside. It is what the simulator can move as kinematic
rigid bodies (one newton mesh shape per capsule's body, :meth:`BodyMesh.pieces`), and the study that
compares it with the capsules (``tools/studies/collider_study.py``, docs/bodies.md) measures both against
the body the viewer sees, the skinned mesh (:mod:`.skinned_body`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.rotations import rotation_between
from ..motion.skeleton import JOINT_INDEX
from .capsules import BodyModel, capsule_signed_distance
from .skinned_body import rest_frames


@dataclass(frozen=True)
class BodyMesh:
    """A body mesh whose vertices each ride with one joint (see the module docstring)."""

    local: np.ndarray  # (V, 3) each vertex in its joint's frame
    faces: np.ndarray  # (F, 3) int64
    joint: np.ndarray  # (V,) the canonical joint each vertex rides with
    capsule: np.ndarray  # (V,) the capsule it was nearest to (its piece)
    rest_rotations: np.ndarray  # (22, 3, 3) the joints' global rotations in the mesh's rest pose
    rest_positions: np.ndarray  # (22, 3)

    def pose(self, global_rotations: np.ndarray, joint_positions: np.ndarray) -> np.ndarray:
        """(T, V, 3) world vertices for FK results (T, 22, 3, 3) and (T, 22, 3)."""
        rot = np.asarray(global_rotations, np.float64)[:, self.joint]
        return np.asarray(joint_positions, np.float64)[:, self.joint] + np.einsum(
            "tvij,vj->tvi", rot, self.local
        )

    def pieces(self, body: BodyModel) -> list[tuple[int, np.ndarray, np.ndarray]]:
        """(capsule index, vertices in that capsule's simulator frame, faces) for each capsule with a
        piece: every face with a vertex on the capsule, so neighbouring pieces overlap by one ring
        and leave no hole at rest. The simulator's frame of a capsule is its centre, +Z along its
        axis (:func:`hrr_garment.sim.scene.capsule_transforms`)."""
        out = []
        for c, capsule in enumerate(body.capsules):
            faces = self.faces[np.isin(self.faces, np.flatnonzero(self.capsule == c)).any(1)]
            if not len(faces):
                continue
            used, compact = np.unique(faces, return_inverse=True)
            a, b = np.asarray(capsule.a, np.float64), np.asarray(capsule.b, np.float64)
            axis = b - a if np.linalg.norm(b - a) > 1e-9 else np.array([0.0, 0.0, 1.0])
            align = rotation_between(np.array([0.0, 0.0, 1.0]), axis)
            # every vertex of the piece in this capsule's joint frame, then in the capsule's frame
            joint = JOINT_INDEX[capsule.joint]
            in_joint = self._in_joint(used, joint)
            out.append((c, (in_joint - 0.5 * (a + b)) @ align, compact.reshape(-1, 3)))
        return out

    def _in_joint(self, vertices: np.ndarray, joint: int) -> np.ndarray:
        """The given vertices, each moved from its own joint's frame into ``joint``'s (rest pose)."""
        rot, pos = self.rest_rotations, self.rest_positions
        world = pos[self.joint[vertices]] + np.einsum(
            "vij,vj->vi", rot[self.joint[vertices]], self.local[vertices]
        )
        return (world - pos[joint]) @ rot[joint]


def body_mesh(body: BodyModel, vertices: np.ndarray, faces: np.ndarray, joints: np.ndarray) -> BodyMesh:
    """``vertices`` (V, 3) and ``faces`` of a rest mesh with its canonical ``joints`` (22, 3) in the
    same pose (an A-pose is fine), cut into rigid pieces along ``body``'s capsules (fitted to it)."""
    vertices = np.asarray(vertices, np.float64)
    rot, pos = rest_frames(body.skeleton, joints)
    a, b = body.pose(rot[None], pos[None])
    _, _, nearest = capsule_signed_distance(vertices, a[0], b[0], radii=body.radii)
    joint = np.array([JOINT_INDEX[body.capsules[c].joint] for c in nearest])
    in_joint = np.einsum("vji,vj->vi", rot[joint], vertices - pos[joint])  # R^T (v - p)
    return BodyMesh(
        in_joint, np.asarray(faces, np.int64), joint, nearest, rest_rotations=rot, rest_positions=pos
    )
