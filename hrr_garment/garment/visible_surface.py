"""The body the viewer sees, as a garment is placed on it: the visible mesh standing in the body's rest
pose, and the signed distance of the garment's vertices from it as they move.

    mesh = rest_mesh(visible, body)           # (V, 3) the skinned mesh in the body's rest (T-)pose
    surface = VisibleSurface(mesh, faces)
    distance, direction = surface.signed(points)   # < 0 inside; direction: outward, unit

Garments are dressed in the body's rest pose (:meth:`~hrr_garment.body.capsules.BodyModel.rest_pose`,
the canonical T-pose on the body's skeleton), while a body's rest mesh stands in its own pose (anny's
A-pose, a character's bind pose): :func:`rest_mesh` skins it into the garment's frame. Measured on
four anny bodies, the mesh as it stands lies 80-120 mm from the body's rest capsules on average, the
skinned one 20-25 mm (the capsules' own fit).

The distance is exact (:func:`~hrr_garment.body.mesh_distance.nearest_on_mesh` on the faces whose
centroids lie nearest); inside or outside is :func:`~hrr_garment.body.mesh_inside.mesh_inside`'s (on a
closed mesh the count of a ray's crossings, in C where the kernel compiles: the generalised winding
number over every face, which an open mesh gets, took most of a garment's dressing, about a second on
anny's mesh), asked again only for a point that moved at least as far as it was from the surface: a
signed distance changes by no more than the point moves, so a nearer move cannot have crossed the
surface.
"""

from __future__ import annotations

import numpy as np

from ..body.capsules import BodyModel
from ..body.mesh_distance import nearest_on_mesh, vertex_normals
from ..body.mesh_inside import is_closed, mesh_inside
from ..body.skinned_body import SkinnedBody

CANDIDATE_FACES = 24  # faces tried per point, by centroid (exact on a body's like-sized faces)


def rest_mesh(visible: SkinnedBody, body: BodyModel) -> np.ndarray:
    """(V, 3) ``visible``'s mesh skinned into ``body``'s rest pose, where garments are dressed: every
    joint's global rotation the identity, the joints at :meth:`~BodyModel.rest_joints`."""
    rotations = np.broadcast_to(np.eye(3), (1, len(visible.rest_positions), 3, 3))
    return visible.pose(rotations, body.rest_joints()[None].astype(np.float64))[0]


class VisibleSurface:
    """Signed distances of a moving point set from a closed triangle mesh (see the module docstring).
    Each call to :meth:`signed` takes the same points, moved."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        self.vertices = np.asarray(vertices, np.float64)
        self.faces = np.asarray(faces, np.int64)
        self.normals = vertex_normals(self.vertices, self.faces)
        self.closed = is_closed(self.faces)  # the ray count where closed, the winding number where not
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # the points last asked about, signed

    def signed(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N,) each point's signed distance (negative inside) and (N, 3) the unit direction in which
        it grows fastest (away from the nearest surface point; the surface's normal on it)."""
        points = np.asarray(points, np.float64)
        unsigned, face, bary = nearest_on_mesh(points, self.vertices, self.faces, candidates=CANDIDATE_FACES)
        corners = self.faces[face]
        nearest = np.einsum("nk,nkc->nc", bary, self.vertices[corners])
        if self._last is None or len(self._last[0]) != len(points):
            inside = self._inside(points)
        else:
            before, signed = self._last
            inside = signed < 0
            crossed = np.linalg.norm(points - before, axis=1) >= np.abs(signed)  # may have crossed
            if crossed.any():
                inside[crossed] = self._inside(points[crossed])
        distance = np.where(inside, -unsigned, unsigned)
        self._last = (points.copy(), distance)
        away = (points - nearest) / np.maximum(unsigned, 1e-12)[:, None]
        normal = np.einsum("nk,nkc->nc", bary, self.normals[corners])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        direction = np.where(
            (unsigned > 1e-6)[:, None], np.where(inside[:, None], -away, away), normal
        )  # on the surface itself the way out is the surface's normal
        return distance, direction

    def _inside(self, points: np.ndarray) -> np.ndarray:
        return mesh_inside(points, self.vertices, self.faces, closed=self.closed)
