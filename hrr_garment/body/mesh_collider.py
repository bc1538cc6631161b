"""The body the viewer sees as the simulator's collider: its skinned mesh, cut into pieces that ride
with the capsules' kinematic bodies and are reshaped every frame to the skinned pose.

    pieces = skinned_pieces(body, visible)           # the capsules fitted to it, its SkinnedBody
    local = pieces.local_frames(motion, centre, quat)  # (T, N, 3): every piece's vertices per frame

Each face of the skinned mesh (:mod:`.skinned_body`) goes to the capsule nearest to it at rest, so
the pieces partition the mesh: no two overlap, and since every vertex is where skinning puts it,
neighbouring pieces meet along their shared edges in every pose. (Rigid pieces, each vertex riding
one bone, overlap on the inside of a bent joint and tore the cloth caught there: 3 of 8 clips in
decision 0039.) The simulator moves each piece's capsule body every substep, as it moves the
capsules; the piece's vertices, in that body's frame (the capsule's centre, +Z along its axis:
:func:`hrr_garment.sim.capsule_poses.capsule_transforms`), are written once a frame, and what
skinning adds to the bone's rigid motion during the frame is the mesh's own velocity, which the
contact's friction reads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.rotations import quat_to_matrix
from .capsules import BodyModel, capsule_signed_distance
from .skinned_body import SkinnedBody


@dataclass(frozen=True)
class MeshPiece:
    """The faces of the skinned mesh that ride with one capsule."""

    capsule: int  # index into the body's capsules
    vertices: np.ndarray  # (n,) int64 the skinned mesh's vertices it uses
    faces: np.ndarray  # (m, 3) int64 into ``vertices``


@dataclass(frozen=True)
class SkinnedPieces:
    """A skinned mesh partitioned into pieces by capsule (see the module docstring)."""

    skin: SkinnedBody
    pieces: tuple[MeshPiece, ...]

    @property
    def offsets(self) -> np.ndarray:
        """(P + 1,) where each piece's vertices start in :meth:`local_frames`' rows."""
        return np.concatenate([[0], np.cumsum([len(p.vertices) for p in self.pieces])])

    def local_frames(self, motion, centre: np.ndarray, quat: np.ndarray) -> np.ndarray:
        """(T, N, 3) float32: every piece's vertices, concatenated in piece order, in its capsule's
        simulator frame on each frame of ``motion`` (on the body's skeleton), the capsules placed
        at ``centre`` (T, C, 3) with rotations ``quat`` (T, C, 4, x y z w)."""
        world = self.skin.pose(motion.global_rotations, motion.joint_positions)  # (T, V, 3)
        turn = quat_to_matrix(np.concatenate([quat[..., 3:], quat[..., :3]], -1))  # (T, C, 3, 3)
        out = [
            np.einsum("tvi,tij->tvj", world[:, p.vertices] - centre[:, p.capsule, None], turn[:, p.capsule])
            for p in self.pieces
        ]
        return np.concatenate(out, 1).astype(np.float32)


def skinned_pieces(body: BodyModel, skin: SkinnedBody) -> SkinnedPieces:
    """``skin`` (the body the viewer sees) cut into one piece per capsule of ``body`` (fitted to it):
    each face goes to the capsule nearest to its centroid with both posed at the skin's rest."""
    a, b = body.pose(skin.rest_rotations[None], skin.rest_positions[None])
    centroids = skin.vertices[skin.faces].mean(1)
    _, _, nearest = capsule_signed_distance(centroids, a[0], b[0], radii=body.radii)
    pieces = []
    for c in range(len(body.capsules)):
        faces = skin.faces[nearest == c]
        if len(faces):
            used, compact = np.unique(faces, return_inverse=True)
            pieces.append(MeshPiece(c, used, compact.reshape(-1, 3)))
    return SkinnedPieces(skin, tuple(pieces))
