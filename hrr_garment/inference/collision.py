"""Collision push-out: garment vertices found inside the posed body are moved just outside.

Per frame, every vertex within ``margin`` of the capsule body (or inside it) is moved along the
nearest capsule's outward normal to ``margin`` outside. Moving only those vertices would leave
one-vertex spikes where a fold dips in; so the push is spread: the displacement field is smoothed
over the mesh (``smooth`` Jacobi passes of the uniform Laplacian, each keeping the pushed vertices'
displacement at least what they need along their normals), so neighbours follow part of the way;
``rounds`` such pushes, then an exact projection guarantees that no vertex ends inside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix, diags

from ..body.capsules import DEFAULT_BODY, BodyModel, capsule_signed_distance
from ..garment.mesh import unique_edges
from ..motion.motion import Motion


@dataclass
class PushOutReport:
    inside_before: float  # mean over frames of the fraction of vertices more than `depth` inside
    inside_after: float
    worst_before: float  # worst frame
    worst_after: float


def mean_operator(faces: np.ndarray, num_vertices: int) -> csr_matrix:
    """(V, V) row-normalised adjacency: each vertex -> mean of its 1-ring."""
    e = unique_edges(faces)
    a = coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), (num_vertices, num_vertices)).tocsr()
    return diags(1.0 / np.maximum(np.asarray(a.sum(1)).ravel(), 1)) @ a


def push_out(vertices: np.ndarray, motion: Motion, faces: np.ndarray, body: BodyModel = DEFAULT_BODY, margin: float = 0.002,
             smooth: int = 4, rounds: int = 3, depth: float = 0.005, mean: csr_matrix | None = None
             ) -> tuple[np.ndarray, PushOutReport]:
    """(T, V, 3) world vertices -> pushed copy and a report (fractions of vertices > ``depth`` inside).
    ``mean``: :func:`mean_operator` of the faces, when the caller keeps one (streaming)."""
    a, b = body.pose_motion(motion)
    radii = body.radii
    from ..models.native import capsule_sdf, load_kernel

    lib = load_kernel()

    def sdf(points, t):
        if lib is None:
            return capsule_signed_distance(points, a[t], b[t], radii)[:2]
        return capsule_sdf(lib, points, a[t], b[t], radii)
    mean = mean_operator(faces, vertices.shape[1]) if mean is None else mean
    out = vertices.astype(np.float32).copy()
    before, after = np.zeros(len(out)), np.zeros(len(out))
    for t in range(len(out)):
        p = out[t].astype(np.float64)
        d, n = sdf(p, t)
        before[t] = (d < -depth).mean()
        for _ in range(rounds):
            need = np.maximum(margin - d, 0.0)  # how far along the normal each vertex must move
            if not need.any():
                break
            hit = need > 0
            disp = need[:, None] * n
            for _ in range(smooth):  # spread the push to the neighbours, never below what is needed
                disp = mean @ disp
                along = (disp[hit] * n[hit]).sum(1)
                disp[hit] += np.maximum(need[hit] - along, 0.0)[:, None] * n[hit]
            moved = np.flatnonzero(np.abs(disp).sum(1) > 0)  # only these need a new distance
            p[moved] += disp[moved]
            d[moved], n[moved] = sdf(p[moved], t)
        for _ in range(4):  # exact projection; repeated where a push lands in another capsule
            inside = np.flatnonzero(d < 0)
            if not len(inside):
                break
            p[inside] += (margin - d[inside])[:, None] * n[inside]
            d[inside], n[inside] = sdf(p[inside], t)
        out[t] = p
        after[t] = (d < -depth).mean()
    return out, PushOutReport(float(before.mean()), float(after.mean()), float(before.max(initial=0)), float(after.max(initial=0)))
