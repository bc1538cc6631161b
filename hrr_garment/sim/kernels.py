"""Warp kernels of the newton scene (imported only with the ``sim`` extra, by :mod:`.scene`)."""

from __future__ import annotations

import warp as wp


@wp.kernel
def scatter_vectors(
    values: wp.array(dtype=wp.vec3), index: wp.array(dtype=wp.int32), vectors: wp.array(dtype=wp.vec3)
):
    """``vectors[index[i]] = values[i]``: the pinned vertices' positions or velocities written on the
    device, without reading every particle back to the host each substep (megabytes per substep in
    a GPU batch)."""
    i = wp.tid()
    vectors[index[i]] = values[i]


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


@wp.kernel
def add_face_normals(
    positions: wp.array(dtype=wp.vec3),
    triangles: wp.array2d(dtype=wp.int32),
    normals: wp.array(dtype=wp.vec3),
):
    """Each triangle's area-weighted normal (twice its area) added to its three vertices' normals
    (``normals`` zeroed before)."""
    t = wp.tid()
    i, j, k = triangles[t, 0], triangles[t, 1], triangles[t, 2]
    n = wp.cross(positions[j] - positions[i], positions[k] - positions[i])
    wp.atomic_add(normals, i, n)
    wp.atomic_add(normals, j, n)
    wp.atomic_add(normals, k, n)


@wp.kernel
def air_drag(
    normals: wp.array(dtype=wp.vec3),
    drag_per_mass: wp.array(dtype=float),
    dt: float,
    velocities: wp.array(dtype=wp.vec3),
):
    """Quadratic air drag on the velocity along each vertex's normal, integrated exactly over ``dt``:
    dv/dt = -c |v| v with c = ``drag_per_mass`` (0.5 * air density * drag coefficient * the vertex's
    area / its mass, per metre; 0 for a pinned vertex). The cloth's motion along itself is not
    damped (air slides along a sheet with little resistance)."""
    i = wp.tid()
    c = drag_per_mass[i]
    n = normals[i]
    length = wp.length(n)
    if c > 0.0 and length > 0.0:
        n = n / length
        v = velocities[i]
        along = wp.dot(v, n)
        kept = along / (1.0 + c * wp.abs(along) * dt)
        velocities[i] = v + (kept - along) * n


@wp.kernel
def zero_vectors(values: wp.array(dtype=wp.vec3)):
    """Every vector zero (inside a captured graph, where a memset is not recorded on every device)."""
    values[wp.tid()] = wp.vec3(0.0, 0.0, 0.0)


@wp.kernel
def relax_velocities(
    velocities: wp.array(dtype=wp.vec3),
    offsets: wp.array(dtype=wp.int32),
    neighbours: wp.array(dtype=wp.int32),
    shares: wp.array(dtype=float),
    relaxed: wp.array(dtype=wp.vec3),
):
    """One explicit step of the cloth's internal friction: each vertex's velocity moves toward its
    neighbours' by ``shares`` (the step's share per neighbour, 0 for a pinned vertex's row), read
    from ``velocities`` and written to ``relaxed`` (every vertex reads the same old velocities)."""
    i = wp.tid()
    v = velocities[i]
    change = wp.vec3(0.0, 0.0, 0.0)
    for k in range(offsets[i], offsets[i + 1]):
        change += shares[k] * (velocities[neighbours[k]] - v)
    relaxed[i] = v + change


@wp.kernel
def copy_vectors(source: wp.array(dtype=wp.vec3), target: wp.array(dtype=wp.vec3)):
    """``target[i] = source[i]`` (inside a captured graph)."""
    i = wp.tid()
    target[i] = source[i]
