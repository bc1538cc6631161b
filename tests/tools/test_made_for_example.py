"""tools/made_for_example.py: on a character's mesh the dress is moved 12 mm off the surface (not off
its nearest vertex, which leaves cloth inside a coarse mesh between its vertices) and kept
left-right symmetric."""

from __future__ import annotations

import numpy as np

from tests.scripts import load_script


def _tool():
    return load_script("tools/made_for_example.py")


def _coarse_sphere(radius=0.1, rings=6, sectors=8):
    """A closed UV sphere of few vertices: its faces lie well inside its vertices' radius."""
    top, bottom = np.array([[0, radius, 0]]), np.array([[0, -radius, 0]])
    ring = [
        radius * np.array([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)])
        for t in np.linspace(0, np.pi, rings + 1)[1:-1]
        for p in np.linspace(0, 2 * np.pi, sectors, endpoint=False)
    ]
    vertices = np.concatenate([top, np.array(ring), bottom])
    faces = []
    for r in range(rings - 1):
        for s in range(sectors):
            a, b = 1 + r * sectors + s, 1 + r * sectors + (s + 1) % sectors
            if r == 0:
                faces.append([0, b, a])
            if r < rings - 2:
                c, d = a + sectors, b + sectors
                faces += [[a, b, d], [a, d, c]]
            else:
                faces.append([a, b, len(vertices) - 1])
    return vertices, np.array(faces)


def test_cloth_ends_twelve_millimetres_off_the_surface_and_symmetric():
    from hrr_garment.body.mesh_distance import nearest_on_mesh
    from hrr_garment.body.mesh_inside import mesh_inside

    tool = _tool()
    skin, faces = _coarse_sphere()
    rng = np.random.default_rng(0)
    half = rng.normal(size=(40, 3))
    half = 0.1 * half / np.linalg.norm(half, axis=1, keepdims=True) * rng.uniform(0.8, 1.3, (40, 1))
    half[:, 0] = np.abs(half[:, 0]) + 0.01
    dress = np.concatenate([half, half * [-1, 1, 1]])  # symmetric, partly inside the skin
    assert mesh_inside(dress, skin, faces).any()
    from scipy.spatial import ConvexHull

    hull = ConvexHull(dress).simplices  # a closed cloth over the points
    placed = tool.off_surface(dress, skin, faces, hull)
    distance = nearest_on_mesh(placed, skin, faces)[0]
    assert not mesh_inside(placed, skin, faces).any()
    assert distance.min() >= tool.SKIN_GAP_M - 1e-3  # nothing nearer than the gap
    near = nearest_on_mesh(dress, skin, faces)[0] < tool.ON_BODY_M
    assert np.median(distance[near]) < 0.03  # drawn onto the body, not left where it was
    np.testing.assert_allclose(placed[40:], placed[:40] * [-1, 1, 1], atol=1e-6)
    # off the nearest vertex instead, cloth stays inside the coarse sphere between its vertices
    old = tool.off_nearest_vertex(dress, skin)
    assert mesh_inside(old, skin, faces).any() or (nearest_on_mesh(old, skin, faces)[0] < 0.006).any()
