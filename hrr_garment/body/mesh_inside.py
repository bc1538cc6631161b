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
says it. Where the C kernel compiles, a closed mesh's count runs there
(:func:`~hrr_garment.native.mesh_probe.mesh_probe`: the same crossings, the faces binned in columns
along +x, about 30 x faster); numpy's count here is its reference and its fallback (``HRR_NATIVE=0``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..native.mesh_probe import mesh_probe
from .mesh_distance import closest_on_triangles, winding_inside

# the rays' frame (the ray is its z axis): nearly level, so that a garment's shadow across the rays
# covers few of a standing body's faces (a skirt's: the hips and thighs, not the head or the shins;
# 2.7 ms a frame against 7.4 for a ray 32 degrees up, a 308-vertex skirt on anny), and along no axis or
# symmetry plane of a body, so that few rays graze an edge (though one that does is counted right)
RAY_FRAME = Rotation.from_euler("xyz", [0.11, 0.23, 0.17]).as_matrix()


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
    """Whether each point lies inside the mesh: the ray count on a closed mesh, the generalised winding
    number on an open one (see the module docstring). ``points`` (N, 3) and ``vertices`` (V, 3) give
    (N,); a batch of frames, (T, N, 3) and (T, V, 3), gives (T, N). ``closed``: :func:`is_closed` of
    ``faces`` where the caller knows it already."""
    if not (is_closed(faces) if closed is None else closed):
        points, vertices = np.asarray(points), np.asarray(vertices)
        frames = zip(points.reshape(-1, *points.shape[-2:]), vertices.reshape(-1, *vertices.shape[-2:]))
        return np.stack([winding_inside(p, v, faces) for p, v in frames]).reshape(points.shape[:-1])
    return np.abs(ray_winding_numbers(points, vertices, faces)) > 0.5


def ray_winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The winding number of each point about a closed mesh, its ray's signed crossings; shapes as
    :func:`mesh_inside`'s."""
    probed = mesh_probe(points, vertices, faces, margin=0.0)  # the kernel's count, where it compiles
    if probed is not None:
        return probed[0].astype(np.float64)
    return _Batch(points, vertices, faces, 0.0).winding().reshape(np.shape(points)[:-1])


class _Batch:
    """Frames of points and of a mesh's vertices, flattened into one set of each (every face and point
    knowing its frame), in the rays' frame, with each point's candidate faces: those whose box across
    the ray, grown by ``grow``, holds the point's shadow (found on a grid of cells, per frame). Only
    the points ``where`` holds (all where None) are taken: ``chosen``, their flat indices."""

    def __init__(
        self,
        points: np.ndarray,
        vertices: np.ndarray,
        faces: np.ndarray,
        grow: float,
        where: np.ndarray | None = None,
    ):
        points, vertices = np.asarray(points, np.float64), np.asarray(vertices, np.float64)
        self.points = points.reshape(-1, *points.shape[-2:])  # (T, N, 3)
        self.vertices = vertices.reshape(-1, *vertices.shape[-2:])  # (T, V, 3)
        frames, n, nv = len(self.points), self.points.shape[1], self.vertices.shape[1]
        self.chosen = (
            np.arange(frames * n) if where is None else np.flatnonzero(np.asarray(where).reshape(-1))
        )
        self.q = (self.points @ RAY_FRAME.T).reshape(-1, 3)[self.chosen]
        self.v = (self.vertices @ RAY_FRAME.T).reshape(-1, 3)
        self.faces = (np.asarray(faces, np.int64)[None] + nv * np.arange(frames)[:, None, None]).reshape(
            -1, 3
        )
        tri = self.v[self.faces]
        self.lo, self.hi = tri.min(1), tri.max(1)  # (T F, 3) the faces' boxes
        self.point, self.face = _candidate_pairs(
            self.q[:, :2],
            self.chosen // n,
            (self.lo[:, :2] - grow, self.hi[:, :2] + grow),
            np.repeat(np.arange(frames), len(faces)),
        )

    def winding(self) -> np.ndarray:
        """(T N,) each point's winding number: the signed crossings of its ray."""
        # in the face's own box, not only the grown one
        shadowed = _in_boxes(self.q, self.point, self.lo, self.hi, self.face)
        point, face = self.point[shadowed], self.face[shadowed]
        crossings = _crossings(self.q[point], self.v, self.faces[face])
        return np.bincount(point, weights=crossings, minlength=len(self.q)).round()


def _candidate_pairs(
    q: np.ndarray, q_frame: np.ndarray, boxes: tuple[np.ndarray, np.ndarray], face_frame: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(M,) points and (M,) faces of the same frame whose 2D ``boxes`` (low and high corners) hold the
    point; ``q`` (N, 2) the points, ``q_frame`` and ``face_frame`` the frames of points and faces."""
    lo, hi = boxes
    # only the faces whose boxes meet their frame's points' box: a skirt's rays meet no head
    frames = int(max(q_frame.max(initial=0), face_frame.max(initial=0))) + 1
    q_lo, q_hi = np.full((frames, 2), np.inf), np.full((frames, 2), -np.inf)
    np.minimum.at(q_lo, q_frame, q)
    np.maximum.at(q_hi, q_frame, q)
    kept = np.flatnonzero(((lo <= q_hi[face_frame]) & (hi >= q_lo[face_frame])).all(1))
    if not len(kept) or not len(q):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    lo, hi, face_frame = lo[kept], hi[kept], face_frame[kept]
    size = max(float(np.median((hi - lo).max(1))), 1e-9)  # a face spans about two cells a side
    origin = lo.min(0)
    first, last = ((lo - origin) // size).astype(np.int64), ((hi - origin) // size).astype(np.int64)
    columns, rows = int(last[:, 0].max()) + 1, int(last[:, 1].max()) + 1
    span = last - first + 1
    counts = span.prod(1)
    face_of = np.repeat(np.arange(len(lo)), counts)
    k = np.arange(len(face_of)) - np.repeat(np.cumsum(counts) - counts, counts)
    column = first[face_of, 0] + k // span[face_of, 1]
    cell = (face_frame[face_of] * columns + column) * rows + first[face_of, 1] + k % span[face_of, 1]
    order = np.argsort(cell, kind="stable")
    cell, face_of = cell[order], face_of[order]
    at = np.floor((q - origin) / size).astype(np.int64)
    on_grid = (at >= 0).all(1) & (at[:, 0] < columns) & (at[:, 1] < rows)
    key = (q_frame * columns + at[:, 0]) * rows + at[:, 1]
    start = np.searchsorted(cell, key, "left")
    n = np.where(on_grid, np.searchsorted(cell, key, "right") - start, 0)
    point = np.repeat(np.arange(len(q)), n)
    offset = np.arange(len(point)) - np.repeat(np.cumsum(n) - n, n)
    face = face_of[np.repeat(start, n) + offset]
    inside = _in_boxes(q, point, lo, hi, face)  # in the box, not only its cells
    return point[inside], kept[face[inside]]


def _in_boxes(
    q: np.ndarray, point: np.ndarray, lo: np.ndarray, hi: np.ndarray, face: np.ndarray
) -> np.ndarray:
    """(M,) whether each point ``q[point]`` lies in its face's box ``lo[face]``-``hi[face]`` across the
    ray (the first two coordinates): compared a coordinate at a time on flat gathers. The pairs are
    millions a batch of frames, and gathering their (M, 2) rows and reducing them took most of
    hrr-eval's measure of the cloth inside a character's mesh (32 frames of a 4,324-vertex dress on anny's
    average body: 1.14 -> 0.67 s a call)."""
    inside = np.ones(len(point), bool)
    for axis in range(2):
        at = np.ascontiguousarray(q[:, axis])[point]
        inside &= at >= np.ascontiguousarray(lo[:, axis])[face]
        inside &= at <= np.ascontiguousarray(hi[:, axis])[face]
    return inside


def _edge_side(v: np.ndarray, a: np.ndarray, b: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The side of each point ``q`` (M, 3) of the directed edge ``a -> b`` across the ray (+1 left, -1
    right) and its edge function. It is the cross product of the ends' offsets from the point, each
    end's offset the same for every edge at that end, so that the edges around a corner that a ray
    (nearly) meets agree; on the line, the point nudged by (e, e^2) decides, the same for both faces
    of an edge (which run along it in opposite directions)."""
    swap = a > b
    start, end = np.where(swap, b, a), np.where(swap, a, b)
    # a coordinate at a time, on flat gathers (as _in_boxes: the pairs are many)
    vx, vy = np.ascontiguousarray(v[:, 0]), np.ascontiguousarray(v[:, 1])
    qx, qy = q[:, 0], q[:, 1]
    rx, ry, sx, sy = vx[start] - qx, vy[start] - qy, vx[end] - qx, vy[end] - qy
    e = rx * sy - ry * sx
    dx, dy = sx - rx, sy - ry  # the edge, lower-numbered end first
    tie = np.where(dy != 0, -np.sign(dy), np.sign(dx))  # e + d_x e^2 - d_y e
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
    points: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    depth: float,
    closed: bool | None = None,
    where: np.ndarray | None = None,
) -> np.ndarray:
    """Whether each point lies inside the mesh (:func:`mesh_inside`) and farther than ``depth`` from its
    surface (the exact distance: every face that could come within ``depth`` is tried); shapes as
    :func:`mesh_inside`'s, a batch of frames at once. ``where`` (the points' shape without the last
    axis): only the points it holds are measured, the others are False."""
    closed = is_closed(faces) if closed is None else closed
    probed = mesh_probe(points, vertices, faces, margin=max(depth, 0.0), where=where) if closed else None
    if probed is not None:  # deeper than depth: inside, and no face within depth (none asked at 0)
        winding, near = probed
        return (winding != 0) & ~(near & (depth > 0))
    batch = _Batch(points, vertices, faces, depth, where)
    if closed:
        deep = np.abs(batch.winding()) > 0.5
    else:
        deep = mesh_inside(batch.points, batch.vertices, faces, closed=False).reshape(-1)[batch.chosen]
    # a face within ``depth`` of a point has the point's shadow in its box grown by ``depth``: the pairs
    near = deep[batch.point] & (depth > 0)
    point, face = batch.point[near], batch.face[near]
    z = batch.q[point, 2]
    near = (z >= batch.lo[face, 2] - depth) & (z <= batch.hi[face, 2] + depth)
    point, face = point[near], face[near]
    p = batch.q[point]
    tri = batch.v[batch.faces[face]]
    gap = np.linalg.norm(p - np.einsum("mk,mkc->mc", closest_on_triangles(p, tri), tri), axis=1)
    deep[point[gap <= depth]] = False
    out = np.zeros(np.shape(points)[:-1], bool)
    out.reshape(-1)[batch.chosen] = deep
    return out
