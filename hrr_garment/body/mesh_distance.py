"""Distances from points to a triangle mesh, in numpy: the nearest point on the surface (its face and
barycentric coordinates), inside or outside by the generalised winding number, and the signed
distance from both. Exact (every face is tried) unless a shortlist of candidate faces is asked for;
what the visible body's colliders are built from (:mod:`.skin_collider`, :mod:`.bone_sdf`) and
measured against.

    distance, face, bary = nearest_on_mesh(points, vertices, faces)
    signed = mesh_signed_distance(points, vertices, faces)        # < 0 inside
"""

from __future__ import annotations

import numpy as np

PAIRS_PER_PASS = 250_000  # point-triangle pairs held at once (a few tens of MB of temporaries)


def closest_on_triangles(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(M, 3) barycentric coordinates of the point of each triangle (M, 3, 3) nearest to each point
    (M, 3), paired row by row (Ericson, *Real-Time Collision Detection* 5.1.5, every case at once)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    ab, ac, ap, bp, cp = b - a, c - a, points - a, points - b, points - c
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        total = va + vb + vc
        v, w = vb / np.where(total != 0, total, 1.0), vc / np.where(total != 0, total, 1.0)
        bary = np.stack([1.0 - v - w, v, w], 1)  # the face's interior; the edges and corners below win
        t = (d4 - d3) / np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) + (d5 - d6), 1.0)
        cases = [
            ((va <= 0) & (d4 >= d3) & (d5 >= d6), np.stack([0 * t, 1 - t, t], 1)),  # edge BC
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), _edge(d2 / np.where(d2 != d6, d2 - d6, 1.0), (0, 2))),
            ((d6 >= 0) & (d5 <= d6), np.array([0.0, 0.0, 1.0])),  # corner C
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), _edge(d1 / np.where(d1 != d3, d1 - d3, 1.0), (0, 1))),
            ((d3 >= 0) & (d4 <= d3), np.array([0.0, 1.0, 0.0])),  # corner B
            ((d1 <= 0) & (d2 <= 0), np.array([1.0, 0.0, 0.0])),  # corner A
        ]
    for mask, value in cases:  # Ericson's tests in reverse: the first that holds is the last written
        bary = np.where(mask[:, None], value, bary)
    return bary


def _edge(t: np.ndarray, ends: tuple[int, int]) -> np.ndarray:
    out = np.zeros((len(t), 3))
    out[:, ends[0]], out[:, ends[1]] = 1.0 - t, t
    return out


def nearest_on_mesh(
    points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, candidates: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N,) each point's distance from the mesh's surface, (N,) the face it is nearest on and (N, 3)
    that point's barycentric coordinates. Every face is tried, or only the ``candidates`` faces whose
    centroids lie nearest (fast, and exact wherever the faces are of like size, as a body's are)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    if candidates is not None and candidates < len(tri):
        from scipy.spatial import cKDTree

        shortlist = cKDTree(tri.mean(1)).query(points, candidates)[1]  # (N, k)
    else:
        shortlist = np.broadcast_to(np.arange(len(tri)), (len(points), len(tri)))
    k = shortlist.shape[1]
    distance, face, bary = np.empty(len(points)), np.empty(len(points), np.int64), np.empty((len(points), 3))
    step = max(1, PAIRS_PER_PASS // k)
    for s in range(0, len(points), step):
        cand = shortlist[s : s + step]
        p = np.repeat(points[s : s + step], k, axis=0)
        t = tri[cand.ravel()]
        b = closest_on_triangles(p, t)
        d = np.linalg.norm(p - np.einsum("mk,mkc->mc", b, t), axis=1).reshape(len(cand), k)
        best = d.argmin(1)
        rows = np.arange(len(cand))
        distance[s : s + step], face[s : s + step] = d[rows, best], cand[rows, best]
        bary[s : s + step] = b.reshape(len(cand), k, 3)[rows, best]
    return distance, face, bary


def within_reach(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, reach: float) -> np.ndarray:
    """(N,) whether some face of the mesh lies within ``reach`` of each point (N, 3), exactly: only the
    pairs whose face's box grown by ``reach`` holds the point are measured (a body's few near ones)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    lo, hi = tri.min(1) - reach, tri.max(1) + reach
    out = np.zeros(len(points), bool)
    step = max(1, PAIRS_PER_PASS // max(len(tri), 1))
    for s in range(0, len(points), step):
        p = points[s : s + step]
        i, f = np.nonzero(((p[:, None] >= lo) & (p[:, None] <= hi)).all(-1))
        bary = closest_on_triangles(p[i], tri[f])
        gap = p[i] - np.einsum("mk,mkc->mc", bary, tri[f])
        out[s + i[(gap * gap).sum(1) <= reach * reach]] = True
    return out


def winding_inside(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) whether each point is inside the triangle mesh: generalised winding number > 0.5, robust
    to the cracks and overlaps of a posed mesh (Jacobson et al. 2013, the solid angle of each face)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    inside = np.empty(len(points), bool)
    step = max(1, PAIRS_PER_PASS // len(tri))
    for s in range(0, len(points), step):
        r = tri[None] - points[s : s + step, None, None, :]  # (n, F, 3, 3)
        a, b, c = r[..., 0, :], r[..., 1, :], r[..., 2, :]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = (a * np.cross(b, c)).sum(-1)
        den = la * lb * lc + (a * b).sum(-1) * lc + (a * c).sum(-1) * lb + (b * c).sum(-1) * la
        inside[s : s + step] = np.abs(2.0 * np.arctan2(det, den).sum(-1) / (4.0 * np.pi)) > 0.5
    return inside


def mesh_signed_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) the exact signed distance of each point from the mesh: negative inside (winding number)."""
    distance = nearest_on_mesh(points, vertices, faces)[0]
    return np.where(winding_inside(points, vertices, faces), -distance, distance)


def surface_samples(
    vertices: np.ndarray, faces: np.ndarray, count: int, *, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points spread evenly by area over the mesh: (count,) their faces and (count, 3)
    barycentric coordinates."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    face = rng.choice(len(tri), count, p=area / area.sum())
    u, v = rng.random((2, count))
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    return face, np.stack([1.0 - u - v, u, v], 1)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) unit normals, each the area-weighted mean of its faces' (outward for a mesh wound
    counter-clockwise seen from outside)."""
    tri = np.asarray(vertices, np.float64)[faces]
    face_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length: twice the area
    out = np.zeros((len(vertices), 3))
    for corner in range(3):
        np.add.at(out, faces[:, corner], face_normals)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
