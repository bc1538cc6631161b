"""The motion memory (hrr_garment.motion.memory): the averages it claims, its invariances, and
the one-frame-at-a-time recursion equal to the clip's closed form."""

import numpy as np
import pytest
from test_features import transformed

from hrr_garment import motion_features, synthesize
from hrr_garment.motion.features import FEATURE_DIM
from hrr_garment.motion.memory import (
    MEMORY_WIDTH,
    MotionMemory,
    check_memory_seconds,
    feature_width,
    with_memory,
)
from hrr_garment.motion.rotations import rotation_about_y, yaw_of
from hrr_garment.motion.skeleton import FEATURE_JOINTS


def world_average(motion, seconds: float) -> np.ndarray:
    """The memory's 3-vector columns computed the long way: world velocities of the feature joints
    and the root, exponentially averaged in the world, turned into each frame's body frame."""
    p = motion.joint_positions[:, [*FEATURE_JOINTS, 0]].astype(np.float64)
    v = np.empty_like(p)
    v[1:] = (p[1:] - p[:-1]) * motion.fps
    v[0] = v[1]  # the offline features' first difference at frame 0
    a = np.exp(-1.0 / (motion.fps * seconds))
    heading = rotation_about_y(yaw_of(motion.global_rotations[:, 0]))
    avg, out = v[0], []
    for t in range(len(v)):
        avg = avg if t == 0 else a * avg + (1 - a) * v[t]
        out.append(avg @ heading[t])  # world -> body frame (heading^T applied to row vectors)
    return np.array(out).reshape(len(v), -1)


@pytest.mark.parametrize("kind", ["walk_curve", "spin", "turn_in_place"])
def test_memory_is_the_world_velocity_average_seen_from_the_body(kind):
    motion = synthesize(kind, seconds=3.0, seed=3)
    got = with_memory(motion_features(motion), motion.fps, (0.5, 1.5))
    assert got.shape == (motion.num_frames, FEATURE_DIM + 2 * MEMORY_WIDTH) == (motion.num_frames, feature_width((0.5, 1.5)))
    for i, seconds in enumerate((0.5, 1.5)):
        cols = slice(FEATURE_DIM + i * MEMORY_WIDTH, FEATURE_DIM + (i + 1) * MEMORY_WIDTH - 1)
        want = world_average(motion, seconds)
        assert np.abs(got[:, cols] - want).max() <= 1e-4 * max(1.0, np.abs(want).max())


def test_memory_of_a_steady_motion_is_its_velocity_and_the_yaw_rate_average_is_plain():
    motion = synthesize("turn_in_place", seconds=3.0, seed=0, turn_rate=60.0)
    f = motion_features(motion)
    got = with_memory(f, motion.fps, (0.25,))
    a = np.exp(-1.0 / (motion.fps * 0.25))
    want = [f[0, -1]]
    for w in f[1:, -1]:
        want.append(a * want[-1] + (1 - a) * w)
    np.testing.assert_allclose(got[:, -1], want, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("kind", ["walk_curve", "dance"])
def test_memory_is_invariant_to_translation_and_vertical_rotation(kind):
    motion = synthesize(kind, seconds=2.0, seed=7)
    base = with_memory(motion_features(motion), motion.fps, (0.5, 1.5))
    for yaw, shift in ((2.5, [0.0, 0.0, 0.0]), (-1.1, [-12.0, 0.0, 40.0])):
        moved = transformed(motion, yaw, shift)
        assert np.abs(with_memory(motion_features(moved), moved.fps, (0.5, 1.5)) - base).max() <= 1e-4


def test_stepping_frame_by_frame_equals_the_clip_and_characters_are_independent():
    clips = [motion_features(synthesize(kind, seconds=2.0, seed=5)) for kind in ("walk_curve", "spin")]
    fps = 30.0
    memory = MotionMemory((0.5, 1.5), fps)
    state = memory.start(np.stack([c[0] for c in clips]))
    rows = [memory.values(state)]
    for t in range(1, len(clips[0])):
        state = memory.step(state, np.stack([c[t] for c in clips]))
        rows.append(memory.values(state))
    stepped = np.stack(rows, 1)  # (2 characters, T, 128)
    for i, clip in enumerate(clips):
        assert np.abs(stepped[i] - with_memory(clip, fps, (0.5, 1.5))[:, FEATURE_DIM:]).max() <= 1e-5


def test_no_time_constants_leaves_the_features_and_bad_ones_are_refused():
    f = motion_features(synthesize("walk", seconds=1.0, seed=0))
    assert with_memory(f, 30.0, ()) is f and feature_width(()) == FEATURE_DIM
    for bad in ((0.0,), (-1.0,), (float("nan"),)):
        with pytest.raises(ValueError, match="positive seconds"):
            check_memory_seconds(bad)
