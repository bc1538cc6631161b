"""The side of a closed mesh from the nearest point's pseudonormal (body/pseudo_normals.py), against
the winding number, on a low-poly ball with saddles and hollows."""

import numpy as np
import pytest

from hrr_garment.body.mesh_distance import mesh_signed_distance, nearest_on_mesh, vertex_normals
from hrr_garment.body.pseudo_normals import edge_neighbours, pseudo_normals

from .limb import bumpy_ball


def test_the_face_across_each_edge_holds_it_reversed_and_an_open_edge_keeps_its_own_face():
    faces = bumpy_ball().faces
    across = edge_neighbours(faces)
    for f in range(len(faces)):
        for e in range(3):
            a, b = faces[f, e], faces[f, (e + 1) % 3]
            other = faces[across[f, e]]
            assert across[f, e] != f and any(other[k] == b and other[(k + 1) % 3] == a for k in range(3))
    open_mesh = faces[1:]  # the first face gone: its three neighbours' edges have no one across
    lonely = edge_neighbours(open_mesh)
    assert (lonely == np.arange(len(open_mesh))[:, None]).sum() == 3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_nearest_points_pseudonormal_tells_the_side_where_shading_normals_do_not(seed):
    ball = bumpy_ball(seed=seed)
    points = np.random.default_rng(1).uniform(-0.16, 0.16, (4000, 3))
    truth = mesh_signed_distance(points, ball.vertices, ball.faces)  # the side by the winding number
    clear = np.abs(truth) > 0.002
    points, truth = points[clear], truth[clear]
    assert 300 < (truth < 0).sum() < len(truth) - 300
    _, face, bary = nearest_on_mesh(points, ball.vertices, ball.faces)
    gap = points - np.einsum("nk,nkc->nc", bary, ball.vertices[ball.faces[face]])
    normals = pseudo_normals(ball.vertices, ball.faces)
    outward = normals.at(ball.faces, face, bary, edge_neighbours(ball.faces))
    assert (((gap * outward).sum(1) < 0) == (truth < 0)).all()
    assert np.allclose(np.linalg.norm(normals.face, axis=1), 1.0)
    assert np.allclose(np.linalg.norm(normals.vertex, axis=1), 1.0)
    # the area-weighted vertex normals interpolated over the face (what a renderer shades with) put
    # some of these points on the wrong side: the ball is a case where the choice matters
    shading = np.einsum("nk,nkc->nc", bary, vertex_normals(ball.vertices, ball.faces)[ball.faces[face]])
    assert (((gap * shading).sum(1) < 0) != (truth < 0)).any()
