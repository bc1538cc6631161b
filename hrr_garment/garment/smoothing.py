"""Smoothing over a garment mesh: the 1-ring mean operator, and the high spatial frequencies that
a few passes of it separate from the rest.

The collision push-out spreads its corrections with the mean operator; the detail mode splits a
garment into its low frequencies (where the cloth is) and its high ones (its folds and wrinkles).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix, diags

from .mesh import unique_edges


def mean_operator(faces: np.ndarray, num_vertices: int) -> csr_matrix:
    """(V, V) row-normalised adjacency: each vertex -> mean of its 1-ring."""
    e = unique_edges(faces)
    a = coo_matrix(
        (np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
        (num_vertices, num_vertices),
    ).tocsr()
    return diags(1.0 / np.maximum(np.asarray(a.sum(1)).ravel(), 1)) @ a


def high_frequencies(vertices: np.ndarray, mean: csr_matrix, passes: int) -> np.ndarray:
    """(T, V, 3) per-frame vertex values -> (T, V, 3) float64: ``x - S^passes x`` with S the
    :func:`mean_operator`, frame by frame. Linear, zero for anything constant over the mesh, and it
    commutes with rotations, so it is the same in the body frame and in the world."""
    t, v = vertices.shape[:2]
    x = np.asarray(vertices, np.float64).transpose(1, 0, 2).reshape(v, 3 * t)  # one sparse product a pass
    low = x
    for _ in range(passes):
        low = mean @ low
    return (x - low).reshape(v, t, 3).transpose(1, 0, 2)
