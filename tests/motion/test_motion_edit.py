"""Motion editing: re-timing and cross-fades (the library protocol's plays)."""

import numpy as np
import pytest

from hrr_garment.motion.edit import aligned, crossfade, retimed
from hrr_garment.motion.rotations import yaw_of
from hrr_garment.motion.synth import synthesize


@pytest.fixture(scope="module")
def walk():
    return synthesize("walk_curve", 3.0, seed=1)


@pytest.fixture(scope="module")
def spin():
    return synthesize("spin", 2.0, seed=2)


def test_retimed_identity_and_length(walk):
    assert retimed(walk, 1.0) is walk
    for speed in (0.9, 1.1, 2.0):
        out = retimed(walk, speed)
        assert out.num_frames == int(np.floor((walk.num_frames - 1) / speed + 1e-4)) + 1
        assert out.fps == walk.fps


def test_retimed_twice_as_fast_keeps_every_other_frame(walk):
    out = retimed(walk, 2.0)
    np.testing.assert_allclose(out.local_rotations, walk.local_rotations[::2][: out.num_frames], atol=1e-5)
    np.testing.assert_allclose(out.root_translation, walk.root_translation[::2][: out.num_frames], atol=1e-12)


def test_retimed_slower_interpolates_between_frames(walk):
    out = retimed(walk, 0.5)  # frame 2k + 1 lies halfway between source frames k and k + 1
    halfway = 0.5 * (walk.root_translation[:-1] + walk.root_translation[1:])
    np.testing.assert_allclose(
        out.root_translation[1::2], halfway[: len(out.root_translation[1::2])], atol=1e-12
    )


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_retimed_rejects_bad_speed(walk, bad):
    with pytest.raises(ValueError, match="speed"):
        retimed(walk, bad)


def test_aligned_sets_heading_and_ground_position(spin):
    out = aligned(spin, 1.0, np.array([2.0, 5.0, -3.0]))
    assert yaw_of(out.global_rotations[0, 0]) == pytest.approx(1.0, abs=1e-5)
    np.testing.assert_allclose(out.root_translation[0, [0, 2]], [2.0, -3.0], atol=1e-9)
    assert out.root_translation[0, 1] == pytest.approx(spin.root_translation[0, 1])  # height kept
    # a rigid motion of the clip: joint-to-joint distances and the path's shape are unchanged
    np.testing.assert_allclose(
        np.linalg.norm(np.diff(out.root_translation, axis=0), axis=1),
        np.linalg.norm(np.diff(spin.root_translation, axis=0), axis=1),
        atol=1e-9,
    )
    np.testing.assert_allclose(out.local_rotations[:, 1:], spin.local_rotations[:, 1:])


def test_crossfade_with_own_continuation_is_identity(walk):
    k, n = 40, 12
    out = crossfade(walk.slice(0, k + n), walk.slice(k, walk.num_frames), n)
    assert out.num_frames == walk.num_frames
    np.testing.assert_allclose(out.local_rotations, walk.local_rotations, atol=1e-5)
    np.testing.assert_allclose(out.root_translation, walk.root_translation, atol=1e-9)


def test_crossfade_keeps_both_clips_outside_the_blend(walk, spin):
    n = 12
    out = crossfade(walk, spin, n)
    start = walk.num_frames - n
    assert out.num_frames == walk.num_frames + spin.num_frames - n
    np.testing.assert_array_equal(out.local_rotations[:start], walk.local_rotations[:start])
    # after the blend: the second clip, turned and moved as a whole (non-root joints untouched)
    np.testing.assert_allclose(out.local_rotations[walk.num_frames :, 1:], spin.local_rotations[n:, 1:])
    tail = out.root_translation[walk.num_frames :]
    np.testing.assert_allclose(
        np.linalg.norm(np.diff(tail, axis=0), axis=1),
        np.linalg.norm(np.diff(spin.root_translation[n:], axis=0), axis=1),
        atol=1e-9,
    )
    # continuous: no frame-to-frame joint jump larger than either clip's own largest
    jumps = np.linalg.norm(np.diff(out.joint_positions, axis=0), axis=-1).max()
    own = max(np.linalg.norm(np.diff(m.joint_positions, axis=0), axis=-1).max() for m in (walk, spin))
    assert jumps < own + 0.05


def test_crossfade_rejects_mismatches(walk, spin):
    with pytest.raises(ValueError, match="fps"):
        crossfade(walk, type(spin)(spin.local_rotations, spin.root_translation, 60.0), 5)
    with pytest.raises(ValueError, match="at least that long"):
        crossfade(walk, spin.slice(0, 4), 5)
