"""Which points lie inside a closed mesh, and within a distance of it, frames at a time, in C
(``mesh_probe.c``, on the push-out's columns): what :mod:`hrr_garment.body.mesh_inside` computes in
numpy, the reference, which it falls back to without a compiler.

    winding, near = mesh_probe(points, vertices, faces, margin=0.005)   # (T, N) int32 and bool
"""

from __future__ import annotations

import numpy as np

from .build import load_kernel
from .threads import default_threads

CELLS_PER_FACE = 1.0  # the columns' width: the faces' median extent across the ray (about 2 cm on anny)


def mesh_probe(
    points: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    margin: float,
    where: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray] | None:
    """For points (..., N, 3) and a closed mesh's vertices (..., V, 3) (the same frames) and faces
    (F, 3): each point's winding number (int32, the signed crossings of its ray along +x) and whether
    a face lies within ``margin`` of it (bool), both shaped as the points without their last axis;
    ``where`` (that shape): only those points are measured (the others 0 and False). None without the
    kernel, for frames that do not pair, or where a frame's columns cannot be built (the caller then
    counts in numpy)."""
    lib = load_kernel()
    shape = np.shape(points)[:-1]
    if lib is None or int(np.prod(shape[:-1])) != int(np.prod(np.shape(vertices)[:-2])):
        return None  # before any copy: the numpy count makes its own
    points = np.ascontiguousarray(points, np.float64).reshape(-1, *np.shape(points)[-2:])
    vertices = np.ascontiguousarray(vertices, np.float64).reshape(-1, *np.shape(vertices)[-2:])
    faces = np.ascontiguousarray(faces, np.int32)
    frames, n, nv = points.shape[0], points.shape[1], vertices.shape[1]
    if not len(faces) or not n or not frames:
        return np.zeros(shape, np.int32), np.zeros(shape, bool)
    extent = np.ptp(vertices[0][faces], axis=1)[:, 1:]  # (F, 2) the faces' extents across the ray, frame 0
    cell = max(float(np.median(extent.max(1))) * CELLS_PER_FACE, 1e-6)
    mask = None if where is None else np.ascontiguousarray(where, np.uint8).reshape(frames, n)
    winding = np.zeros((frames, n), np.int32)
    near = np.zeros((frames, n), np.uint8)
    ok = lib.hrr_mesh_probe(
        faces.ctypes.data,
        len(faces),
        nv,
        frames,
        vertices.ctypes.data,
        n,
        points.ctypes.data,
        None if mask is None else mask.ctypes.data,
        float(margin),
        cell,
        winding.ctypes.data,
        near.ctypes.data,
        default_threads(),
    )
    return (winding.reshape(shape), near.astype(bool).reshape(shape)) if ok else None
