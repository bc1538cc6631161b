"""Which points lie inside a triangle mesh, and more than a depth inside it, fast enough to measure every
frame of a garment against the body the viewer sees (hrr-eval's headline plausibility figure).

    inside = mesh_inside(points, vertices, faces)                 # (N,) bool
    deep = inside_deeper_than(points, vertices, faces, depth=0.005)  # (N,) bool: more than 5 mm inside

On a closed mesh (every edge shared by two faces that run along it in opposite directions, as
anny's is in every pose: skinning moves vertices, not the topology) the winding number of a point is
an integer, and it equals the signed count of the mesh's crossings of a ray from the point: that
count is what :func:`mesh_inside` computes, with the faces binned on a grid across the ray so that
each point tries only the few faces in front of or behind it (a few in a thousand of a body's),
instead of every face's solid angle (:func:`~.mesh_distance.winding_inside`, about 100 x slower). Each
edge's side is decided once for both its faces, a tie broken by the same symbolic nudge of the point,
so a ray through an edge or a corner crosses the mesh exactly once (watertight). An open mesh (a
character's, with its eyes or clothes as separate shells) has no such integer: there
:func:`mesh_inside` is the generalised winding number over 0.5 (Jacobson et al. 2013), every face
tried. Inside means a winding number of magnitude 1 or more, as :func:`~.mesh_distance.winding_inside`
says it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from .mesh_distance import closest_on_triangles, winding_inside

# the rays' frame: a fixed direction that no axis or symmetry plane of a body lies along (the ray is
# this frame's z axis; fewer rays graze an edge, though a grazing ray is counted right anyway)
RAY_FRAME = Rotation.from_euler("xyz", [0.61, 0.37, 0.23]).as_matrix()


def is_closed(faces: np.ndarray) -> bool:
    """Whether the mesh is closed and consistently wound: each directed edge once, and its reverse once."""
    faces = np.asarray(faces, np.int64)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    forward = np.unique(directed, axis=0)
    return len(forward) == len(directed) and bool(
        (np.unique(np.concatenate([forward, directed[:, ::-1]]), axis=0).shape[0] == len(forward))
    )


def mesh_inside(
    points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, *, closed: bool | None = None
) -> np.ndarray:
    """(N,) whether each point lies inside the mesh: the ray count on a closed mesh, the generalised
    winding number on an open one (see the module docstring); ``closed``: :func:`is_closed` of
    ``faces`` where the caller knows it already."""
    if not (is_closed(faces) if closed is None else closed):
        return winding_inside(points, vertices, faces)
    return np.abs(ray_winding_numbers(points, vertices, faces)) > 0.5


def ray_winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) the winding number of each point about a closed mesh: its ray's signed crossings."""
    q = np.asarray(points, np.float64).reshape(-1, 3) @ RAY_FRAME.T
    v = np.asarray(vertices, np.float64) @ RAY_FRAME.T
    faces = np.asarray(faces, np.int64)
    point, face = _candidate_pairs(q[:, :2], v[:, :2], faces)
    return np.bincount(point, weights=_crossings(q[point], v, faces[face]), minlength=len(q)).round()


def _candidate_pairs(q: np.ndarray, v: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M,) points and (M,) faces whose 2D boxes share a grid cell with them, across the ray."""
    lo, hi = v[faces].min(1), v[faces].max(1)
    size = max(float(np.median((hi - lo).max(1))), 1e-9)  # a face spans about two cells a side
    origin = lo.min(0)
    first, last = ((lo - origin) // size).astype(np.int64), ((hi - origin) // size).astype(np.int64)
    rows = int(last[:, 1].max()) + 1
    span = last - first + 1
    counts = span.prod(1)
    face_of = np.repeat(np.arange(len(faces)), counts)
    k = np.arange(len(face_of)) - np.repeat(np.cumsum(counts) - counts, counts)
    cell = (first[face_of, 0] + k // span[face_of, 1]) * rows + first[face_of, 1] + k % span[face_of, 1]
    order = np.argsort(cell, kind="stable")
    cell, face_of = cell[order], face_of[order]
    at = np.floor((q - origin) / size).astype(np.int64)
    on_grid = (at >= 0).all(1) & (at[:, 0] <= last[:, 0].max()) & (at[:, 1] < rows)
    key = at[:, 0] * rows + at[:, 1]
    start = np.searchsorted(cell, key, "left")
    n = np.where(on_grid, np.searchsorted(cell, key, "right") - start, 0)
    point = np.repeat(np.arange(len(q)), n)
    offset = np.arange(len(point)) - np.repeat(np.cumsum(n) - n, n)
    face = face_of[np.repeat(start, n) + offset]
    boxed = ((q[point] >= lo[face]) & (q[point] <= hi[face])).all(1)  # in the face's box, not only its cells
    return point[boxed], face[boxed]


def _edge_side(v: np.ndarray, a: np.ndarray, b: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The side of each point ``q`` (M, 3) of the directed edge ``a -> b`` across the ray (+1 left, -1
    right) and its edge function. It is the cross product of the ends' offsets from the point, each
    end's offset the same for every edge at that end, so that the edges around a corner that a ray
    (nearly) meets agree; on the line, the point nudged by (e, e^2) decides, the same for both faces
    of an edge (which run along it in opposite directions)."""
    swap = a > b
    start, end = np.where(swap, b, a), np.where(swap, a, b)
    r, s = v[start, :2] - q[:, :2], v[end, :2] - q[:, :2]
    e = r[:, 0] * s[:, 1] - r[:, 1] * s[:, 0]
    d = s - r  # the edge, lower-numbered end first
    tie = np.where(d[:, 1] != 0, -np.sign(d[:, 1]), np.sign(d[:, 0]))  # e + d_x e^2 - d_y e
    side = np.where(e != 0, np.sign(e), tie)
    flip = np.where(swap, -1.0, 1.0)
    return flip * side, flip * e


def _crossings(q: np.ndarray, v: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(M,) +1 or -1 where the ray from each point (M, 3) up the z axis crosses its face (its corners
    (M, 3)) in front of the point, by the face's winding as seen along the ray; 0 where it does not."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    side_ab, e_ab = _edge_side(v, a, b, q)
    side_bc, e_bc = _edge_side(v, b, c, q)
    side_ca, e_ca = _edge_side(v, c, a, q)
    hit = (side_ab == side_bc) & (side_bc == side_ca) & (side_ab != 0)
    total = e_ab + e_bc + e_ca  # twice the face's area across the ray
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (e_bc * v[a, 2] + e_ca * v[b, 2] + e_ab * v[c, 2]) / total
    return np.where(hit & (total != 0) & (z > q[:, 2]), side_ab, 0.0)


def inside_deeper_than(
    points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, *, depth: float, closed: bool | None = None
) -> np.ndarray:
    """(N,) whether each point lies inside the mesh (:func:`mesh_inside`) and farther than ``depth``
    from its surface (the exact distance: every face that could lie within ``depth`` is tried)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    deep = mesh_inside(points, vertices, faces, closed=closed)
    if not deep.any() or depth <= 0:
        return deep
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    centre = tri.mean(1)
    reach = np.linalg.norm(tri - centre[:, None], axis=-1).max(1)  # each face lies within this of its centre
    inside = np.flatnonzero(deep)
    pairs = cKDTree(points[inside]).sparse_distance_matrix(
        cKDTree(centre), depth + float(reach.max()), output_type="ndarray"
    )
    keep = pairs["v"] <= depth + reach[pairs["j"]]  # only the faces that can come within ``depth``
    owner, candidate = pairs["i"][keep].astype(np.int64), pairs["j"][keep].astype(np.int64)
    p = points[inside][owner]
    bary = closest_on_triangles(p, tri[candidate])
    gap = np.linalg.norm(p - np.einsum("mk,mkc->mc", bary, tri[candidate]), axis=1)
    deep[inside[np.unique(owner[gap <= depth])]] = False
    return deep
