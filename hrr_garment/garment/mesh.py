"""Garment meshes: the triangle mesh, its named vertex groups, checks and repairs.

A garment is one connected, consistently wound triangle mesh with at least one *attached* vertex
group (a waistband, straps) that follows the body; everything else is free cloth. Checks raise
:class:`GarmentError` naming the mesh and the problem; repairs are explicit and documented in
docs/garments.md (polygon triangulation happens in the OBJ reader).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from ..errors import InputError


class GarmentError(InputError):
    """A garment mesh that cannot be simulated or learned from."""


@dataclass(frozen=True)
class GarmentMesh:
    """Vertices (V, 3) float32 in the canonical rest pose (Y up, metres), faces (F, 3) int32.

    ``groups`` maps names to vertex index arrays (``waistband``, ``straps``, ``hem``...);
    ``attached_groups`` names the groups whose vertices are skinned to the body.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    groups: dict[str, np.ndarray] = field(default_factory=dict)
    attached_groups: tuple[str, ...] = ()

    @property
    def attached(self) -> np.ndarray:
        """Sorted indices of every attached vertex (int32)."""
        parts = [self.groups[g] for g in self.attached_groups if g in self.groups]
        return np.unique(np.concatenate(parts)).astype(np.int32) if parts else np.zeros(0, np.int32)

    @property
    def num_vertices(self) -> int:
        return int(self.vertices.shape[0])

    def edges(self) -> np.ndarray:
        return unique_edges(self.faces)


def unique_edges(faces: np.ndarray) -> np.ndarray:
    """Undirected edges (E, 2) with i < j, sorted, each once."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of each triangle, (F,)."""
    tri = vertices[faces]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=-1)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals, (..., V, 3) from (..., V, 3) positions: the mean of the adjacent faces'
    unit normals, each weighted by the face's angle at the vertex, on the winding's side. Angle
    weighting is what Blender, Maya and USD renderers compute: on a folded dress, area weighting
    (three.js's ``computeVertexNormals``) leans 22 degrees away from it at the 99th percentile, so
    a file carrying area-weighted normals shades differently from the same mesh recomputed there.
    A vertex with no face, or whose faces cancel, gets +Y: renderers expect unit vectors."""
    from scipy.sparse import csr_matrix

    v = np.asarray(vertices, np.float64)
    num = v.shape[-2]
    tri = v[..., faces, :]  # (..., F, 3 corners, 3)
    cross = np.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :])  # (..., F, 3)
    area2 = np.linalg.norm(cross, axis=-1, keepdims=True)
    unit = np.where(area2 > 1e-30, cross / np.maximum(area2, 1e-300), 0.0)  # degenerate faces add nothing
    normals = np.zeros((num, *v.shape[:-2], 3))
    for k in range(3):  # each corner: the angle between its two edges, atan2 being exact near 0 and pi
        u, w = tri[..., (k + 1) % 3, :] - tri[..., k, :], tri[..., (k + 2) % 3, :] - tri[..., k, :]
        angle = np.arctan2(np.linalg.norm(np.cross(u, w), axis=-1), (u * w).sum(-1))  # (..., F)
        corner = csr_matrix(
            (np.ones(len(faces)), (faces[:, k], np.arange(len(faces)))), shape=(num, len(faces))
        )
        weighted = np.moveaxis(unit * angle[..., None], -2, 0).reshape(len(faces), -1)  # (F, ... x 3)
        normals += (corner @ weighted).reshape(normals.shape)
    normals = np.moveaxis(normals, 0, -2)
    length = np.linalg.norm(normals, axis=-1, keepdims=True)
    return np.where(length > 1e-20, normals / np.maximum(length, 1e-300), np.array([0.0, 1.0, 0.0]))


def _directed_edge_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per undirected edge: (edge (E,2), faces using it, faces using it in the i->j direction)."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    forward = directed[:, 0] < directed[:, 1]
    key = np.sort(directed, axis=1)
    edges, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    fwd = np.bincount(inverse.ravel(), weights=forward, minlength=len(edges)).astype(int)
    return edges, counts, fwd


def components(num_vertices: int, faces: np.ndarray) -> np.ndarray:
    """Connected-component label per vertex (vertices in no face get their own components)."""
    return edge_components(num_vertices, unique_edges(faces))


def edge_components(num_vertices: int, edges: np.ndarray) -> np.ndarray:
    """Connected-component label per vertex of the graph of ``edges`` (E, 2) (a vertex on no edge
    is its own component)."""
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(num_vertices, num_vertices))
    return connected_components(graph, directed=False)[1]


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """The (E, 2) edges used by one face only: the mesh's open boundary (i < j)."""
    edges, counts, _ = _directed_edge_counts(np.asarray(faces))
    return edges[counts == 1]


def check_garment(mesh: GarmentMesh, min_area: float = 1e-10) -> None:
    """Raise :class:`GarmentError` unless the mesh can be simulated (see module docstring)."""
    v, f, who = mesh.vertices, mesh.faces, mesh.name
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
        raise GarmentError(who, f"vertices must be (V>=3, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise GarmentError(who, f"faces must be (F>=1, 3) triangles, got {f.shape}")
    if not np.isfinite(v).all():
        raise GarmentError(who, "vertex positions contain NaN or infinity")
    if f.min() < 0 or f.max() >= len(v):
        raise GarmentError(who, f"face indices must lie in [0, {len(v)}), found {f.min()}..{f.max()}")
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    tiny = face_areas(v, f) <= min_area
    if (repeated | tiny).any():
        bad = np.flatnonzero(repeated | tiny)
        raise GarmentError(
            who,
            f"{len(bad)} degenerate faces (zero area), first: {bad[:5].tolist()}; "
            "repair with repair_mesh(drop_degenerate=True)",
        )
    unused = np.setdiff1d(np.arange(len(v)), f.ravel())
    if len(unused):
        raise GarmentError(who, f"{len(unused)} vertices belong to no face, first: {unused[:5].tolist()}")
    edges, counts, fwd = _directed_edge_counts(f)
    if (counts > 2).any():
        bad = edges[counts > 2]
        raise GarmentError(
            who, f"{len(bad)} non-manifold edges (shared by more than two faces), first: {bad[:3].tolist()}"
        )
    flipped = (counts == 2) & (fwd != 1)
    if flipped.any():
        raise GarmentError(
            who,
            f"inconsistent winding across {int(flipped.sum())} edges, first: "
            f"{edges[flipped][:3].tolist()}; repair with repair_mesh(fix_winding=True)",
        )
    labels = components(len(v), f)
    n_comp = int(labels.max()) + 1
    if n_comp > 1:
        sizes = np.bincount(labels)
        raise GarmentError(
            who,
            f"mesh has {n_comp} connected components (vertex counts "
            f"{sorted(sizes.tolist(), reverse=True)[:5]}); a garment must be one piece",
        )
    for name, idx in mesh.groups.items():
        if len(idx) and (idx.min() < 0 or idx.max() >= len(v)):
            raise GarmentError(who, f"vertex group {name!r} has indices outside [0, {len(v)})")
    if len(mesh.attached) == 0:
        raise GarmentError(
            who,
            "no attached vertices: name a vertex group (e.g. 'waistband') or an "
            "index file whose vertices follow the body",
        )


def repair_mesh(
    mesh: GarmentMesh, merge_tolerance: float = 1e-6, drop_degenerate: bool = True, fix_winding: bool = True
) -> GarmentMesh:
    """Merge duplicate vertices, drop degenerate faces and unused vertices, make winding consistent.

    Vertex groups are remapped onto the merged vertices. Winding is propagated from face 0 across
    shared edges (per connected component); the result's orientation is then arbitrary but
    consistent, so the caller may want outward normals checked separately.
    """
    v, f = mesh.vertices.astype(np.float64), mesh.faces.astype(np.int64)
    # Merge vertices closer than the tolerance (quantise, then unique).
    keys = np.round(v / merge_tolerance).astype(np.int64)
    _, first, remap = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    remap = remap.ravel()
    order = np.argsort(first)  # keep the original order of first occurrences
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    remap = rank[remap]
    v, f = v[first[order]], remap[f]
    if drop_degenerate:
        ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2]) & (face_areas(v, f) > 1e-12)
        f = f[ok]
    used = np.unique(f.ravel())
    compact = -np.ones(len(v), np.int64)
    compact[used] = np.arange(len(used))
    v, f = v[used], compact[f]
    remap = compact[remap]
    groups = {k: np.unique(remap[idx][remap[idx] >= 0]).astype(np.int32) for k, idx in mesh.groups.items()}
    if fix_winding:
        f = _orient_faces(f)
    return GarmentMesh(mesh.name, v.astype(np.float32), f.astype(np.int32), groups, mesh.attached_groups)


def _orient_faces(faces: np.ndarray) -> np.ndarray:
    """Flip faces so that neighbours traverse their shared edge in opposite directions."""
    faces = faces.copy()
    n = len(faces)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    owner = np.tile(np.arange(n), 3)
    key = np.sort(directed, axis=1)
    _, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    order = np.argsort(inverse, kind="stable")
    inv_sorted = inverse[order]
    pair = np.flatnonzero(inv_sorted[1:] == inv_sorted[:-1])  # manifold edges: consecutive entries
    a, b = order[pair], order[pair + 1]
    adj = coo_matrix(
        (np.ones(len(a) * 2), (np.r_[owner[a], owner[b]], np.r_[owner[b], owner[a]])), shape=(n, n)
    ).tocsr()
    flip = np.zeros(n, bool)
    visited = np.zeros(n, bool)
    same_dir = {}
    for ea, eb in zip(a, b):
        same_dir[(owner[ea], owner[eb])] = same_dir[(owner[eb], owner[ea])] = bool(
            (directed[ea] == directed[eb]).all()
        )
    for seed in range(n):
        if visited[seed]:
            continue
        order_bfs, preds = breadth_first_order(adj, seed, directed=False, return_predecessors=True)
        visited[order_bfs] = True
        for face in order_bfs[1:]:
            parent = preds[face]
            flip[face] = flip[parent] ^ same_dir[(parent, face)]
    faces[flip] = faces[flip][:, ::-1]
    return faces


def mirror_map(vertices: np.ndarray, tolerance: float = 1e-6) -> np.ndarray | None:
    """The left-right mirror permutation of a template symmetric about the plane x = 0, or None.

    Returns ``perm`` such that ``vertices[perm] * (-1, 1, 1) == vertices`` within ``tolerance``
    metres. A mirrored frame of a symmetric garment is what the simulator gives for the mirrored
    motion, up to the triangulation: quads split along one diagonal mirror onto the other diagonal,
    which changes the cloth's response only at the scale of one triangle.
    """
    from scipy.spatial import cKDTree

    mirrored = np.asarray(vertices, np.float64) * np.array([-1.0, 1.0, 1.0])
    dist, perm = cKDTree(np.asarray(vertices, np.float64)).query(mirrored)
    if dist.max() > tolerance or len(np.unique(perm)) != len(perm):
        return None
    return perm.astype(np.int64)
