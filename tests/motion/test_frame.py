"""The body frame (hrr_garment.motion.frame): to and from the pelvis-following frame, in double and
in float32 (the world_vertices kernel and its fallback)."""

import numpy as np
import pytest

from hrr_garment.motion.frame import from_body_frame, to_body_frame
from hrr_garment.motion.synth import synthesize


def test_from_body_frame_inverts_the_body_frame(rng):
    motion = synthesize("turn_in_place", 1.0, seed=3)
    points = rng.normal(size=(motion.num_frames, 5, 3))
    assert np.allclose(from_body_frame(to_body_frame(points, motion), motion), points, atol=1e-9)


@pytest.mark.native
@pytest.mark.parametrize("native", ["1", "0"])
def test_world_vertices_are_the_body_frame_inverse_in_float32(rng, monkeypatch, native):
    """The kernel (and its fallback) rounds what from_body_frame computes in double: within one
    float32 step of it, frame by frame, one frame alone as in a batch."""
    from hrr_garment.motion.frame import world_vertices

    monkeypatch.setenv("HRR_NATIVE", native)
    motion = synthesize("walk_curve", 1.0, seed=4)
    points = rng.normal(size=(motion.num_frames, 300, 3)).astype(np.float32)
    got = world_vertices(points, motion)
    ref = from_body_frame(points, motion)
    assert got.dtype == np.float32 and got.shape == points.shape
    assert np.abs(got - ref).max() <= 2 * np.spacing(np.float32(np.abs(ref).max()))
    assert np.array_equal(world_vertices(points[7:8], motion.slice(7, 8))[0], got[7])


def test_body_frame_follows_the_pelvis_height_and_heading():
    from hrr_garment.motion.rotations import rotation_about_y, yaw_of
    from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT

    motion = synthesize("jump", 1.5, seed=1)  # the pelvis dips and rises
    assert np.ptp(motion.root_translation[:, 1]) > 0.1
    offset = np.array([[0.1, -0.3, 0.2], [-0.2, 0.1, 0.05]])  # carried rigidly with the pelvis heading
    world = motion.root_translation[:, None] + np.einsum(
        "tij,nj->tni", rotation_about_y(yaw_of(motion.global_rotations[:, 0])), offset
    )
    local = to_body_frame(world, motion)
    assert np.allclose(local, offset + [0.0, REST_PELVIS_HEIGHT, 0.0], atol=1e-9)
