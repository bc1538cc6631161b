"""Inside a mesh by signed ray crossings, counted in numpy (the reference) and by the C kernel
(native/mesh_probe.c, on the push-out's columns): the same answer as the generalised winding number
on a closed mesh, also where a ray runs exactly through a corner or along an edge; an open mesh falls
back to the winding number; the depth is the exact distance to the surface; the two counts agree on
frames of a moving mesh, some points left out."""

import numpy as np
import pytest

from hrr_garment.body.mesh_distance import mesh_signed_distance, winding_inside
from hrr_garment.body.mesh_inside import (
    RAY_FRAME,
    inside_deeper_than,
    is_closed,
    mesh_inside,
    ray_winding_numbers,
)


def box(half: float = 0.1, splits: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A closed cube of side 2 ``half`` around the origin, each side a ``splits`` x ``splits`` grid of
    squares cut into two triangles, wound outward."""
    grid = np.linspace(-half, half, splits + 1)
    vertices, faces = [], []
    for axis in range(3):
        for side in (-1.0, 1.0):
            u, w = [a for a in range(3) if a != axis]
            start = len(vertices)
            for i in grid:
                for j in grid:
                    p = np.zeros(3)
                    p[axis], p[u], p[w] = side * half, i, j
                    vertices.append(p)
            n = splits + 1
            for i in range(splits):
                for j in range(splits):
                    a, b, c, d = (
                        start + k for k in (i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1)
                    )
                    faces += [(a, b, c), (a, c, d)]
    vertices, faces = np.array(vertices), np.array(faces)
    # one copy of each corner and edge point, so that the sides share their edges
    unique, index = np.unique(np.round(vertices, 12), axis=0, return_inverse=True)
    faces = index.reshape(-1)[faces]
    tri = unique[faces]
    outward = (np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * tri.mean(1)).sum(1) > 0
    return unique, np.where(outward[:, None], faces, faces[:, ::-1])


@pytest.fixture(params=["1", "0"], ids=["kernel", "numpy"])
def counted_by(request, monkeypatch):
    """Each test of the count twice: by the C kernel (where it compiles) and by numpy's reference."""
    monkeypatch.setenv("HRR_NATIVE", request.param)
    return request.param


def test_the_ray_count_is_the_winding_number_on_a_closed_mesh(rng, counted_by):
    one = box()
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    # two boxes overlapping (as a posed body's limbs overlap at a bent joint): 2 where both
    two = (
        np.concatenate([one[0], one[0] @ turn.T * 0.8 + [0.08, 0.05, 0.0]]),
        np.concatenate([one[1], one[1] + len(one[0])]),
    )
    for vertices, faces in (one, two):
        assert is_closed(faces)
        lo, hi = vertices.min(0) - 0.05, vertices.max(0) + 0.05
        points = lo + rng.random((3000, 3)) * (hi - lo)
        expected = winding_inside(points, vertices, faces)
        assert 0.05 < expected.mean() < 0.95
        np.testing.assert_array_equal(mesh_inside(points, vertices, faces), expected)
    assert np.abs(ray_winding_numbers(np.array([[0.08, 0.05, 0.0]]), *two)) == 2


def test_a_ray_through_a_corner_or_along_an_edge_crosses_once(counted_by, rng):
    vertices, faces = box(splits=3)
    if counted_by == "1":  # the kernel's rays run along +x: the cube turned, so that none lies on a side
        vertices = vertices @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T
        ray = np.array([1.0, 0.0, 0.0])
    else:
        ray = RAY_FRAME[2]  # numpy's rays' direction in the world
    on_edges = (vertices[faces[:, 0]] + vertices[faces[:, 1]]) / 2
    for targets in (vertices, on_edges):
        for before in (0.05, 0.3):  # the point inside the cube, then outside it, its ray through the target
            points = targets - before * ray
            count = ray_winding_numbers(points, vertices, faces)
            expected = winding_inside(points, vertices, faces)
            np.testing.assert_array_equal(np.abs(count) > 0.5, expected)
            assert set(np.abs(count).tolist()) <= {0.0, 1.0}


def test_an_open_mesh_is_the_generalised_winding_number(rng):
    vertices, faces = box()
    open_faces = faces[1:]  # a hole
    assert not is_closed(open_faces) and not is_closed(np.concatenate([faces, faces[:1]]))
    points = rng.uniform(-0.12, 0.12, (500, 3))
    np.testing.assert_array_equal(
        mesh_inside(points, vertices, open_faces), winding_inside(points, vertices, open_faces)
    )


@pytest.mark.parametrize("depth", [0.0, 0.005, 0.02])
def test_inside_deeper_than_counts_the_exact_depth(depth, rng, counted_by):
    vertices, faces = box()
    points = rng.uniform(-0.13, 0.13, (2000, 3))
    signed = mesh_signed_distance(points, vertices, faces)
    np.testing.assert_array_equal(inside_deeper_than(points, vertices, faces, depth=depth), signed < -depth)
    # on a side's middle, 3 mm and 8 mm in: only the deeper is more than 5 mm in
    known = np.array([[0.097, 0.01, -0.02], [0.092, 0.01, -0.02], [0.11, 0.0, 0.0], [0.0, 0.0, 0.0]])
    assert inside_deeper_than(known, vertices, faces, depth=0.005).tolist() == [False, True, False, True]


@pytest.mark.native
def test_the_kernel_counts_what_numpy_counts_on_frames_of_a_moving_mesh(rng, monkeypatch):
    """Two boxes overlapping, turned and moved frame by frame (a posed body's limbs overlap at a bent
    joint): winding numbers, the points deeper than 5 mm and those of the points ``where`` keeps, the
    same from both counts."""
    one = box(splits=3)
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    rest = np.concatenate([one[0], one[0] @ turn.T * 0.8 + [0.08, 0.05, 0.0]])
    faces = np.concatenate([one[1], one[1] + len(one[0])])
    frames = np.stack(
        [rest @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T + rng.normal(scale=0.05, size=3) for _ in range(5)]
    )
    points = frames.mean(1, keepdims=True) + rng.uniform(-0.2, 0.2, (5, 4000, 3))
    where = rng.random((5, 4000)) < 0.5
    answers = {}
    for native in ("1", "0"):
        monkeypatch.setenv("HRR_NATIVE", native)
        answers[native] = (
            ray_winding_numbers(points, frames, faces),
            inside_deeper_than(points, frames, faces, depth=0.005, closed=True),
            inside_deeper_than(points, frames, faces, depth=0.005, closed=True, where=where),
        )
    assert 0.05 < answers["0"][1].mean() < 0.5 and (np.abs(answers["0"][0]) == 2).any()
    for kernel, reference in zip(answers["1"], answers["0"]):
        np.testing.assert_array_equal(kernel, reference)
    assert not answers["1"][2][~where].any()
