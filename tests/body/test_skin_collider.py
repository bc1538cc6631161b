"""The inverse-skinning collider: the exact signed distance to the mesh at rest and under a rigid
motion, within its stated distance of the exact distance to a skinned limb bent 90 degrees and to a
curled chain of six joints, on the right side of points a centimetre inside and outside the bend,
and a body it cannot hold refused by name."""

import dataclasses

import numpy as np
import pytest

from hrr_garment.body.mesh_distance import mesh_signed_distance
from hrr_garment.body.skin_collider import SkinColliderSettings, skin_collider
from hrr_garment.motion.rotations import axis_angle_to_matrix

from .limb import (
    ELBOW,
    LENGTH,
    RADIUS,
    bent,
    bumpy_ball,
    curled,
    near_surface,
    skinned_chain,
    skinned_limb,
    turned_halves,
)

SETTINGS = SkinColliderSettings(voxel_m=0.01, padding_m=0.03)


@pytest.fixture(scope="module")
def limb_and_collider():
    limb = skinned_limb()
    return limb, skin_collider(limb, SETTINGS)


def test_at_rest_and_moved_rigidly_it_is_the_mesh(limb_and_collider):
    limb, collider = limb_and_collider
    points, _ = near_surface(limb, limb.vertices, count=60)
    # off the vertices' normals, where two faces are equally near and either's normal is right
    points += np.random.default_rng(1).normal(scale=0.002, size=points.shape)
    exact = mesh_signed_distance(points, limb.vertices, limb.faces)
    here, here_normal = collider.query(points, limb.rest_rotations, limb.rest_positions)
    # a node lists every face that can be nearest to a point nearest to it: the exact distance
    assert np.abs(here - exact).max() < 1e-9
    # the whole limb turned and moved: the same distances, the normals turned with it
    turn = axis_angle_to_matrix(np.array([0.7, 0.2, -1.3]))
    shift = np.array([0.3, 1.0, -0.4])
    rot, pos = limb.rest_rotations, limb.rest_positions
    there, there_normal = collider.query(points @ turn.T + shift, turn @ rot, pos @ turn.T + shift)
    assert np.abs(there - here).max() < 1e-9 and np.abs(there_normal - here_normal @ turn.T).max() < 1e-9
    # along the side the outward normal points away from the axis, inside and out
    side = (np.abs(here) > 0.004) & (points[:, 0] > 0.03) & (points[:, 0] < LENGTH - 0.03)
    radial = points[side] * [0.0, 1.0, 1.0]
    assert ((here_normal[side] * radial).sum(1) / np.linalg.norm(radial, axis=1) > 0.95).all()
    assert collider.nbytes < 2_000_000


def test_bent_ninety_degrees_it_follows_the_skinned_mesh(limb_and_collider):
    limb, collider = limb_and_collider
    rot, pos = bent(90.0)
    posed = limb.pose(rot[None], pos[None])[0]
    # posed vertices, and 5 and 20 mm off them both ways
    points, _ = near_surface(limb, posed, count=50)
    exact = mesh_signed_distance(points, posed, limb.faces)
    distance, normal = collider.query(points, rot, pos)
    error = np.abs(distance - exact)
    # within 3 mm everywhere (the module docstring), exact but for a few points
    assert error.max() < 0.003 and np.median(error) < 1e-9
    assert (np.abs(np.linalg.norm(normal, axis=1) - 1.0) < 1e-9).all()
    # points a centimetre or more inside and outside the bent limb near its elbow: each on its side
    axes = [np.linspace(ELBOW - 0.1, ELBOW + 0.1, 9), np.linspace(-0.1, 0.1, 9), np.linspace(-0.07, 0.07, 6)]
    grid = np.stack(np.meshgrid(*axes), -1).reshape(-1, 3)
    signed = mesh_signed_distance(grid, posed, limb.faces)
    clear = (np.abs(signed) > 0.01) & (np.abs(signed) < RADIUS)
    assert (signed[clear] < 0).sum() > 20 and (signed[clear] > 0).sum() > 20
    got = collider.query(grid[clear], rot, pos)[0]
    assert (np.sign(got) == np.sign(signed[clear])).all()
    assert np.abs(got - signed[clear]).max() < 0.006


def test_curled_on_a_chain_of_six_joints_blended_all_along_it_follows_the_mesh():
    # every vertex between two joints (as broadly blended as anny's skin), each joint turned 30
    # degrees and twisted 20 from its parent: 150 degrees in all, every start chosen among six
    chain = skinned_chain(6)
    collider = skin_collider(chain, SETTINGS)
    rot, pos = curled(chain, 30.0, 20.0)
    posed = chain.pose(rot[None], pos[None])[0]
    points, _ = near_surface(chain, posed, count=60)
    exact = mesh_signed_distance(points, posed, chain.faces)
    distance = collider.query(points, rot, pos)[0]
    assert np.abs(distance - exact).max() < 0.002 and np.median(np.abs(distance - exact)) < 1e-9
    clear = np.abs(exact) > 0.003
    assert (np.sign(distance[clear]) == np.sign(exact[clear])).all()
    # and anywhere about it, up to 30 cm off: never inside where it is not (rest points deep in the
    # chain are carried off by the joint whose skin is nearest, far from any skin)
    around = np.random.default_rng(4).uniform(-0.3, 0.3, (300, 3)) + posed.mean(0)
    exact = mesh_signed_distance(around, posed, chain.faces)
    clear = np.abs(exact) > 0.003
    assert (np.sign(collider.query(around[clear], rot, pos)[0]) == np.sign(exact[clear])).all()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_on_a_low_poly_ball_with_saddles_and_hollows_every_point_is_on_its_side(seed):
    # the nearest face's side by its pseudonormal (body/pseudo_normals.py): the shading normals
    # interpolated over a face put points centimetres outside a coarse mesh's saddles inside
    ball = bumpy_ball(seed=seed)
    collider = skin_collider(ball, SETTINGS)
    rot, pos = turned_halves(ball, 30.0)
    posed = ball.pose(rot[None], pos[None])[0]
    points = np.random.default_rng(1).uniform(-0.16, 0.16, (3000, 3))
    exact = mesh_signed_distance(points, posed, ball.faces)
    clear = np.abs(exact) > 0.003
    distance = collider.query(points[clear], rot, pos)[0]
    assert (np.sign(distance) == np.sign(exact[clear])).all()
    assert np.abs(distance - exact[clear]).max() < 0.01


def test_a_body_it_cannot_hold_is_refused_by_name(limb_and_collider):
    limb, collider = limb_and_collider
    no_faces = dataclasses.replace(limb, faces=np.zeros((0, 3), np.int64))
    with pytest.raises(ValueError, match="no faces"):
        skin_collider(no_faces, SETTINGS)
    from hrr_garment.native.skin import SkinKernel

    many = dataclasses.replace(collider, settings=dataclasses.replace(SETTINGS, starts=9))
    with pytest.raises(ValueError, match="1 to 8 starts"):
        SkinKernel(many, None)
