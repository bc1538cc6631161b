"""Collision push-out: garment vertices found inside the posed body are moved just outside.

Per frame, every vertex within ``margin`` of the capsule body (or inside it) is moved along the
nearest capsule's outward normal to ``margin`` outside. Moving only those vertices would leave
one-vertex spikes where a fold dips in; so the push is spread: the displacement field is smoothed
over the mesh (``smooth`` Jacobi passes of the uniform Laplacian, each keeping the pushed vertices'
displacement at least what they need along their normals), so neighbours follow part of the way;
``rounds`` such pushes, then up to four exact projections onto the surface (a push can land in a
neighbouring capsule, hence more than one). With a C compiler the same steps run in the kernel of
:mod:`hrr_garment.native` (frames in parallel); this module's numpy version is the
reference and the fallback.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix, diags

from ..body.capsules import DEFAULT_BODY, BodyModel, frames_signed_distance
from ..garment.mesh import unique_edges
from ..motion.motion import Motion


@dataclass
class PushOutReport:
    """How much of the garment was inside the body before and after the push-out."""

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
             smooth: int = 4, rounds: int = 1, depth: float = 0.005, mean: csr_matrix | None = None,
             chunk: int = 64) -> tuple[np.ndarray, PushOutReport]:
    """(T, V, 3) world vertices -> pushed copy and a report (fractions of vertices > ``depth`` inside).
    ``mean``: :func:`mean_operator` of the faces, when the caller keeps one (streaming). Frames are
    processed ``chunk`` at a time, all at once within a chunk."""
    a, b = body.pose_motion(motion)
    mean = mean_operator(faces, vertices.shape[1]) if mean is None else mean
    out = np.empty(vertices.shape, np.float32)
    before, after = np.zeros(len(out)), np.zeros(len(out))
    from ..native import default_threads, load_kernel, push_out_frames

    lib = load_kernel()
    for start in range(0, len(out), chunk):
        sl = slice(start, start + chunk)
        if lib is not None:  # the same steps in C, frames in parallel: numpy's per-step overheads dominated
            out[sl], before[sl], after[sl] = push_out_frames(lib, vertices[sl], a[sl], b[sl], body.radii, mean, margin, smooth,
                                                             rounds, depth, threads=default_threads())
        else:
            out[sl], before[sl], after[sl] = _push_frames(vertices[sl].astype(np.float64), a[sl], b[sl], body.radii, mean,
                                                          margin, smooth, rounds, depth)
    return out, PushOutReport(float(before.mean()), float(after.mean()), float(before.max(initial=0)), float(after.max(initial=0)))


def _push_frames(p: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray, mean: csr_matrix, margin: float,
                 smooth: int, rounds: int, depth: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference (and the path without a C compiler): whole-mesh arrays, frames at once."""
    t, v = p.shape[:2]
    d, n = frames_signed_distance(p, a, b, radii)
    before = (d < -depth).mean(1)
    for _ in range(rounds):
        need = np.maximum(margin - d, 0.0)  # how far along the normal each vertex must move
        if not need.any():
            break
        hit = need > 0
        disp = need[..., None] * n
        for _ in range(smooth):  # spread the push to the neighbours, never below what is needed
            disp = (mean @ disp.transpose(1, 0, 2).reshape(v, -1)).reshape(v, t, 3).transpose(1, 0, 2)
            short = np.where(hit, np.maximum(need - (disp * n).sum(-1), 0.0), 0.0)
            disp += short[..., None] * n
        p = p + disp
        d, n = frames_signed_distance(p, a, b, radii)
    for _ in range(4):  # exact projection; repeated where a push lands in another capsule
        inside = d < 0
        if not inside.any():
            break
        p = p + np.where(inside, margin - d, 0.0)[..., None] * n
        d, n = frames_signed_distance(p, a, b, radii)
    return p.astype(np.float32), before, (d < -depth).mean(1)
