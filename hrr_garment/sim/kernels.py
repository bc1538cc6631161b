"""Warp kernels of the newton scene (imported only with the ``sim`` extra, by :mod:`.scene`)."""

from __future__ import annotations

import warp as wp


@wp.kernel
def scatter_positions(
    values: wp.array(dtype=wp.vec3), index: wp.array(dtype=wp.int32), positions: wp.array(dtype=wp.vec3)
):
    """``positions[index[i]] = values[i]``: the pinned vertices written on the device, without
    reading every particle back to the host each substep (megabytes per substep in a GPU batch)."""
    i = wp.tid()
    positions[index[i]] = values[i]


@wp.kernel
def mesh_signed_distance(
    mesh: wp.uint64, points: wp.array(dtype=wp.vec3), max_dist: float, distance: wp.array(dtype=float)
):
    """Each point's distance from the mesh's surface, negative inside it by the (fast) generalised
    winding number, which holds on a posed mesh's cracks and overlaps; ``max_dist`` where no face
    lies nearer than that (the sign is then unknown and taken as outside)."""
    i = wp.tid()
    inside = float(0.0)
    face = int(0)
    u = float(0.0)
    v = float(0.0)
    d = max_dist
    if wp.mesh_query_point_sign_winding_number(mesh, points[i], max_dist, inside, face, u, v):
        d = wp.length(points[i] - wp.mesh_eval_position(mesh, face, u, v))
        if inside < 0.0:
            d = -d
    distance[i] = d
