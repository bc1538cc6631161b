"""tools/studies/face_push_study.py: the experimental push of the cloth's faces off the skin's vertices."""

from __future__ import annotations

import numpy as np
import pytest

from hrr_garment.body.mesh_distance import nearest_on_mesh, vertex_normals
from tests.scripts import load_script

pytestmark = pytest.mark.tool


def _tool():
    return load_script("tools/studies/face_push_study.py")


def _grid(n: int, size: float, height: float):
    """An n x n grid of vertices over [-size, size]^2 at y = height (a cloth above a floor of skin)."""
    u = np.linspace(-size, size, n)
    x, z = np.meshgrid(u, u, indexing="ij")
    vertices = np.stack([x.ravel(), np.full(n * n, height), z.ravel()], 1)
    k = np.arange(n * n).reshape(n, n)
    a, b, c, d = k[:-1, :-1].ravel(), k[1:, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, 1:].ravel()
    faces = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])  # normals +y
    return vertices, faces


def test_a_skin_peak_through_a_cloth_face_ends_under_it_by_the_clearance():
    tool = _tool()
    cloth, cloth_faces = _grid(5, 0.1, 0.0)  # 5 cm cells: their faces span the peak
    skin, skin_faces = _grid(9, 0.12, -0.01)  # a floor 1 cm below the cloth ...
    peak = int(np.argmin(np.linalg.norm(skin[:, [0, 2]] - [0.012, 0.013], axis=1)))
    skin[peak, 1] = 0.004  # ... with one vertex 4 mm through the cloth, inside a face
    moved = tool.keep_skin_out_of_faces(cloth, cloth_faces, skin, skin_faces, clearance=0.003)
    normal = vertex_normals(skin, skin_faces)[peak]
    assert normal[1] > 0.5  # the peak's normal points up, through the cloth
    # the cloth over the peak (its height there, barycentric) is now at least the clearance above it
    _, face, bary = nearest_on_mesh(skin[peak : peak + 1], moved, cloth_faces)
    above = bary[0] @ moved[cloth_faces[face[0]]] - skin[peak]
    assert above @ normal >= 0.003 - 1e-4
    # only the faces over the peak moved: the cloth's far corners stay put; nothing was pulled down
    far = np.linalg.norm(cloth[:, [0, 2]], axis=1) > 0.08
    assert np.allclose(moved[far], cloth[far]) and np.all(moved[:, 1] >= cloth[:, 1] - 1e-12)
