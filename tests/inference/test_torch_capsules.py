"""The exportable push-out's capsule distances (hrr_garment.inference.torch_capsules) against the
package's (hrr_garment.body.capsules): the crowd's distances from their folded products, the normals
measured only where a push reads them, and the scattered points' coordinate-plane form."""

import numpy as np
import pytest


def _crowd(rng, dtype):
    """A mannequin's 20 capsules posed for 3 characters (3 frames of a dance, about each pelvis) and
    400 points a character spread from deep inside to 15 cm off the body."""
    import torch

    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.motion.synth import synthesize

    dance = synthesize("dance", 1.0, seed=2)
    frames = [0, 12, 24]
    a, b = DEFAULT_BODY.pose(dance.global_rotations[frames], dance.joint_positions[frames])
    pelvis = dance.joint_positions[frames][:, :1]
    a, b = a - pelvis, b - pelvis
    centres = (a + b) / 2
    picked = rng.integers(0, a.shape[1], (3, 400))
    points = np.take_along_axis(centres, picked[..., None], 1) + rng.normal(0.0, 0.09, (3, 400, 3))
    radii = np.broadcast_to(DEFAULT_BODY.radii, (3, 1, len(DEFAULT_BODY.radii)))
    as_torch = lambda x: torch.tensor(np.ascontiguousarray(x), dtype=dtype)  # noqa: E731
    return (points, a, b, radii), tuple(as_torch(x) for x in (points, a, b, radii))


def _reference(points, a, b, radii):
    from hrr_garment.body.capsules import frames_signed_distance

    return frames_signed_distance(points, a, b, radii[:, 0])


@pytest.mark.parametrize("dtype_name, tolerance", [("float64", 1e-9), ("float32", 1e-5)])
def test_the_crowd_distances_are_the_capsules_and_their_normals_only_where_read(rng, dtype_name, tolerance):
    import torch

    from hrr_garment.inference.torch_capsules import capsule_distance_within

    arrays, tensors = _crowd(rng, getattr(torch, dtype_name))
    d_ref, n_ref = _reference(*arrays)
    within = 0.02
    points, a, b, radii = tensors
    d, n = (x.numpy() for x in capsule_distance_within(points, a, b, radii=radii, within=within))
    near = d_ref < within
    assert 0.2 < near.mean() < 0.9 and (d_ref < 0).any()  # both sides of the cut, and points inside
    assert np.abs(d - d_ref).max() < tolerance  # the folded products' cancellation stays in float32's reach
    assert np.abs(n[near] - n_ref[near]).max() < 10 * tolerance
    assert np.all(n[d >= within] == 0.0)  # nobody reads them: not measured


def test_scattered_points_each_against_their_own_characters_capsules(rng):
    import torch

    from hrr_garment.inference.torch_capsules import per_point, point_capsule_distance

    arrays, (points, a, b, radii) = _crowd(rng, torch.float64)
    d_ref, n_ref = _reference(*arrays)
    rows = torch.from_numpy(rng.choice(points.shape[0] * points.shape[1], 300, replace=False))
    character = torch.div(rows, points.shape[1], rounding_mode="floor")
    d, n = point_capsule_distance(
        torch.index_select(points.reshape(-1, 3), 0, rows), per_point(character, a, b, radii=radii[:, 0])
    )
    assert np.abs(d.numpy() - d_ref.reshape(-1)[rows]).max() < 1e-12
    assert np.abs(n.numpy() - n_ref.reshape(-1, 3)[rows]).max() < 1e-9
