"""Points against a mesh posed frame by frame (the body the viewer sees): their signed distances,
and pinned points moved out of it. Warp's BVH and fast winding number, so only with the ``sim``
extra; a mesh of a thousand faces and a thousand points take about 15 ms a frame on one core."""

from __future__ import annotations

import numpy as np

MAX_DIST_M = 1.0  # distances are exact within this of the surface, this beyond


def _query(points: np.ndarray, posed: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, N) signed distances and (T, N, 3) outward directions (:func:`~.kernels.mesh_signed_distance`)
    of points (T, N, 3) from the mesh posed at (T, M, 3) with ``faces``."""
    import warp as wp

    from .kernels import mesh_signed_distance

    distance_out = np.empty(points.shape[:2], np.float32)
    outward_out = np.empty(points.shape, np.float32)
    indices = wp.array(np.asarray(faces, np.int32).ravel(), dtype=wp.int32, device="cpu")
    distance = wp.empty(points.shape[1], dtype=float, device="cpu")
    outward = wp.empty(points.shape[1], dtype=wp.vec3, device="cpu")
    for t in range(len(points)):
        mesh = wp.Mesh(
            points=wp.array(np.asarray(posed[t], np.float32), dtype=wp.vec3, device="cpu"),
            indices=indices,
            support_winding_number=True,
        )
        frame = wp.array(np.asarray(points[t], np.float32), dtype=wp.vec3, device="cpu")
        wp.launch(
            mesh_signed_distance,
            dim=len(frame),
            inputs=[mesh.id, frame, MAX_DIST_M],
            outputs=[distance, outward],
        )
        distance_out[t], outward_out[t] = distance.numpy(), outward.numpy()
    return distance_out, outward_out


def mesh_signed_distances(points: np.ndarray, posed: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(T, N) signed distance of each point (T, N, 3) from a mesh posed frame by frame (T, M, 3) with
    ``faces``: negative inside, by winding number (robust to a posed mesh's cracks and overlaps)."""
    return _query(points, posed, faces)[0]


CLEAR_PASSES = 3  # a mesh of overlapping parts: a point moved out through one may be inside another


def clear_of_mesh(points: np.ndarray, posed: np.ndarray, faces: np.ndarray, clearance: float) -> np.ndarray:
    """``points`` (T, N, 3) with each one inside the posed mesh, or nearer its surface than
    ``clearance``, moved out along the surface's outward direction to ``clearance`` from it (again,
    up to :data:`CLEAR_PASSES` times, where that left it inside another overlapping part)."""
    out = np.asarray(points, np.float64).copy()
    for _ in range(CLEAR_PASSES):
        distance, outward = _query(out, posed, faces)
        short = np.maximum(clearance - distance, 0.0)
        if not (short > 1e-4 * clearance).any():
            break
        out += short[..., None] * outward
    return out.astype(np.asarray(points).dtype)
