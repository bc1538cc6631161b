"""A cloth mesh's edges, hinges and energies: the discrete membrane (stretch) and shell (bending)
energies the evaluation's sharpness is measured with (docs/evaluation.md) and the generative
decoder's temperature is calibrated on (:mod:`hrr_garment.train.sampler_calibration`).

Stretch E_s = sum_e l0_e (l_e / l0_e - 1)^2 over edges (rest lengths l0 from the template);
bending E_b = sum_e (theta_e - theta0_e)^2 l0_e / h0_e over interior edges (Grinspun et al. 2003:
theta the dihedral angle, h0_e a third of the summed heights of the two rest triangles over e),
up to material constants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MeshTopology:
    """Edges and the two faces of each interior edge, from a triangle list (computed once)."""

    faces: np.ndarray  # (F, 3)
    edges: np.ndarray  # (E, 2) unique, sorted pairs
    interior: np.ndarray  # (I,) indices into edges of the edges with exactly two faces
    wings: np.ndarray  # (I, 2) the two faces of each interior edge
    opposite: np.ndarray  # (I, 2) the vertex of each wing face not on the edge
    num_vertices: int

    @classmethod
    def of(cls, faces: np.ndarray, num_vertices: int) -> "MeshTopology":
        faces = np.asarray(faces, np.int64)
        corner = np.stack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]], 1).reshape(-1, 2)
        opp = faces[:, [2, 0, 1]].reshape(-1)
        face_of = np.repeat(np.arange(len(faces)), 3)
        key = np.sort(corner, 1)
        edges, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        inverse = inverse.reshape(-1)
        order = np.argsort(inverse, kind="stable")
        starts = np.r_[0, np.cumsum(counts)[:-1]]
        interior = np.flatnonzero(counts == 2)
        first, second = order[starts[interior]], order[starts[interior] + 1]
        return cls(
            faces,
            edges,
            interior,
            np.stack([face_of[first], face_of[second]], 1),
            np.stack([opp[first], opp[second]], 1),
            num_vertices,
        )


def _planes(v: np.ndarray) -> np.ndarray:
    """(3, ..., V) the coordinate planes of vertices ``v`` (..., V, 3), each contiguous: the gathers
    and products below run a plane at a time, where a trailing axis of three made numpy's cross
    products and norms the evaluation's slowest part (three times faster; the same operations in the
    same order give the same lengths and angles, bit for bit, now laid out row by row, so that a sum
    over a frame's edges may differ in its last bits)."""
    return np.ascontiguousarray(np.moveaxis(np.asarray(v), -1, 0))


def _norm(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """|(x, y, z)|, summed as numpy's norm sums a last axis of three"""
    return np.sqrt(x * x + y * y + z * z)


def _cross(a: tuple, b: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """a x b of two vectors given as their three planes (numpy's cross product, term for term)"""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


def edge_lengths(v: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(..., E) the lengths of ``edges`` (E, 2) of vertices ``v`` (..., V, 3)."""
    d = [np.take(p, edges[:, 1], -1) - np.take(p, edges[:, 0], -1) for p in _planes(v)]
    return _norm(*d)


def dihedral_angles(v: np.ndarray, topo: MeshTopology) -> np.ndarray:
    """(..., I) unsigned angle between the normals of the two faces of each interior edge."""
    planes = _planes(v)
    corners = [[np.take(p, topo.faces[:, k], -1) for p in planes] for k in range(3)]  # [corner][axis]
    u = [corners[1][k] - corners[0][k] for k in range(3)]
    w = [corners[2][k] - corners[0][k] for k in range(3)]
    n = _cross(u, w)
    size = np.maximum(_norm(*n), 1e-20)
    n = [c / size for c in n]
    a = [np.take(c, topo.wings[:, 0], -1) for c in n]  # np.take: C-ordered, where indexing the last
    b = [np.take(c, topo.wings[:, 1], -1) for c in n]  # axis gives it last-axis-first (sums would differ)
    # atan2 of |a x b| and a . b: accurate for small angles, where arccos loses digits
    return np.arctan2(_norm(*_cross(a, b)), a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


def rest_hinge_heights(rest: np.ndarray, topo: MeshTopology) -> np.ndarray:
    """h0_e: a third of the summed heights of the two rest triangles over each interior edge."""
    e = topo.edges[topo.interior]
    base = np.linalg.norm(rest[e[:, 1]] - rest[e[:, 0]], axis=-1)
    heights = []
    for k in range(2):
        apex = rest[topo.opposite[:, k]]
        area2 = np.linalg.norm(np.cross(rest[e[:, 1]] - rest[e[:, 0]], apex - rest[e[:, 0]]), axis=-1)
        heights.append(area2 / np.maximum(base, 1e-12))
    return (heights[0] + heights[1]) / 3.0


def cloth_energies(v: np.ndarray, rest: np.ndarray, topo: MeshTopology) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame (stretch, bending) energies up to material constants (see the module docstring)."""
    l0 = np.maximum(edge_lengths(rest, topo.edges), 1e-12)
    stretch = (l0 * (edge_lengths(v, topo.edges) / l0 - 1.0) ** 2).sum(-1)
    e0 = l0[topo.interior]
    theta0 = dihedral_angles(rest, topo)
    bend = (
        (dihedral_angles(v, topo) - theta0) ** 2 * e0 / np.maximum(rest_hinge_heights(rest, topo), 1e-12)
    ).sum(-1)
    return stretch, bend
