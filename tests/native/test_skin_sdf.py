"""The inverse-skinning collider's C kernel (native/skin_sdf.c) against its numpy reference
(body/skin_collider.py) on the skinned limb, straight and bent, and on a curled chain of six joints."""

import numpy as np
import pytest

from hrr_garment.body.skin_collider import SkinColliderSettings, skin_collider
from tests.body.limb import (
    ELBOW,
    bent,
    bumpy_ball,
    curled,
    near_surface,
    skinned_chain,
    skinned_limb,
    turned_halves,
)

pytestmark = pytest.mark.native


@pytest.fixture(scope="module")
def limb_and_collider():
    limb = skinned_limb()
    return limb, skin_collider(limb, SkinColliderSettings(voxel_m=0.01, padding_m=0.03))


@pytest.mark.parametrize("degrees", [0.0, 90.0, 135.0])
def test_native_skin_distance_equals_numpy(limb_and_collider, degrees):
    from hrr_garment.native import load_kernel
    from hrr_garment.native.skin import SkinKernel

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    limb, collider = limb_and_collider
    rot, pos = bent(degrees)
    posed = limb.pose(rot[None], pos[None])[0]
    # near the skin, and anywhere about the limb (in its grid and beyond it)
    around = np.random.default_rng(0).uniform(-0.15, 0.15, (400, 3)) + [ELBOW, 0.0, 0.0]
    points = np.concatenate([near_surface(limb, posed, count=60)[0], around * [2.0, 1.0, 1.0]])
    points += np.random.default_rng(1).normal(scale=1e-4, size=points.shape)  # off the vertices' ties
    distance, normal = collider.query(points, rot, pos)
    native_distance, native_normal = SkinKernel(collider, lib).query(points, rot, pos)
    assert np.abs(native_distance - distance).max() < 1e-12
    assert np.abs(native_normal - normal).max() < 1e-9


def test_native_skin_distance_equals_numpy_on_a_curled_chain():
    from hrr_garment.native import load_kernel
    from hrr_garment.native.skin import SkinKernel

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    # six joints: more than the three starts, each picked from the guesses of all six
    chain = skinned_chain(6)
    collider = skin_collider(chain, SkinColliderSettings(voxel_m=0.01, padding_m=0.03))
    rot, pos = curled(chain, 30.0, 20.0)
    posed = chain.pose(rot[None], pos[None])[0]
    around = np.random.default_rng(2).uniform(-0.1, 0.1, (400, 3)) + posed.mean(0)
    points = np.concatenate([near_surface(chain, posed, count=60)[0], around * [2.0, 2.0, 1.0]])
    points += np.random.default_rng(3).normal(scale=1e-4, size=points.shape)
    distance, normal = collider.query(points, rot, pos)
    native_distance, native_normal = SkinKernel(collider, lib).query(points, rot, pos)
    assert np.abs(native_distance - distance).max() < 1e-12
    assert np.abs(native_normal - normal).max() < 1e-9


def test_native_skin_distance_equals_numpy_on_a_low_poly_ball():
    # the pseudonormals' three cases (a face, an edge, a corner) all met on its saddles and hollows
    from hrr_garment.native import load_kernel
    from hrr_garment.native.skin import SkinKernel

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    ball = bumpy_ball()
    collider = skin_collider(ball, SkinColliderSettings(voxel_m=0.01, padding_m=0.03))
    rot, pos = turned_halves(ball, 30.0)
    points = np.random.default_rng(1).uniform(-0.16, 0.16, (2000, 3))
    distance, normal = collider.query(points, rot, pos)
    native_distance, native_normal = SkinKernel(collider, lib).query(points, rot, pos)
    assert np.abs(native_distance - distance).max() < 1e-12
    assert np.abs(native_normal - normal).max() < 1e-9
