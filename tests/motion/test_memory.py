"""The motion memory (hrr_garment.motion.memory): the averages and resonators it claims (against
the long hand in the world and a pendulum's known response), its invariances, and the
one-frame-at-a-time recursion equal to the clip's closed form."""

import numpy as np
import pytest

from hrr_garment import motion_features, synthesize
from hrr_garment.motion.compose import held_still
from hrr_garment.motion.features import FEATURE_DIM
from hrr_garment.motion.memory import (
    LONG_STILL_S,
    MEMORY_WIDTH,
    MemorySettings,
    MotionMemory,
    check_memory_seconds,
    clock_step,
    feature_width,
    moving_fraction,
    resonator_step,
    still_clock,
    with_memory,
)
from hrr_garment.motion.rotations import rotation_about_y, yaw_of
from hrr_garment.motion.skeleton import FEATURE_JOINTS
from tests.motion.test_features import transformed

RESONATING = MemorySettings((0.5, 1.5), (0.6, 1.0, 1.6), 0.3)
CLOCKED = MemorySettings((0.5, 1.5), (0.6, 1.0, 1.6), still_seconds=(1.0, 4.0))
HELD = MemorySettings((0.5,), (1.0,), still_seconds=(1.0,), held_seconds=(0.5, 2.0))


def world_velocities(motion) -> np.ndarray:
    """(T, 21, 3) world velocities of the feature joints and the root, as the offline features
    difference them, and (T, 3, 3) each frame's heading."""
    p = motion.joint_positions[:, [*FEATURE_JOINTS, 0]].astype(np.float64)
    v = np.empty_like(p)
    v[1:] = (p[1:] - p[:-1]) * motion.fps
    v[0] = v[1]  # the offline features' first difference at frame 0
    return v, rotation_about_y(yaw_of(motion.global_rotations[:, 0]))


def world_average(motion, seconds: float) -> np.ndarray:
    """The memory's 3-vector columns computed the long way: world velocities of the feature joints
    and the root, exponentially averaged in the world, turned into each frame's body frame."""
    v, heading = world_velocities(motion)
    a = np.exp(-1.0 / (motion.fps * seconds))
    avg, out = v[0], []
    for t in range(len(v)):
        avg = avg if t == 0 else a * avg + (1 - a) * v[t]
        out.append(avg @ heading[t])  # world -> body frame (heading^T applied to row vectors)
    return np.array(out).reshape(len(v), -1)


def world_resonator(motion, hz: float, damping: float) -> tuple[np.ndarray, np.ndarray]:
    """A resonator's 3-vector columns (w x and q) the long way: pendulums hung from the world
    velocities, stepped in the world from rest, turned into each frame's body frame."""
    v, heading = world_velocities(motion)
    a, b = resonator_step(hz, damping, motion.fps)
    x, q, out = np.zeros_like(v[0]), v[0], []
    for t in range(len(v)):
        if t:
            x, q = a[0, 0] * x + a[0, 1] * q + b[0] * v[t], a[1, 0] * x + a[1, 1] * q + b[1] * v[t]
        out.append((2 * np.pi * hz * x @ heading[t], q @ heading[t]))
    return tuple(np.array([o[i] for o in out]).reshape(len(v), -1) for i in range(2))


@pytest.mark.parametrize("kind", ["walk_curve", "spin", "turn_in_place"])
def test_memory_is_the_world_velocity_average_seen_from_the_body(kind):
    motion = synthesize(kind, seconds=3.0, seed=3)
    got = with_memory(motion_features(motion), motion.fps, (0.5, 1.5))
    assert (
        got.shape
        == (motion.num_frames, FEATURE_DIM + 2 * MEMORY_WIDTH)
        == (motion.num_frames, feature_width((0.5, 1.5)))
    )
    for i, seconds in enumerate((0.5, 1.5)):
        cols = slice(FEATURE_DIM + i * MEMORY_WIDTH, FEATURE_DIM + (i + 1) * MEMORY_WIDTH - 1)
        want = world_average(motion, seconds)
        assert np.abs(got[:, cols] - want).max() <= 1e-4 * max(1.0, np.abs(want).max())


@pytest.mark.parametrize("kind", ["walk_curve", "spin"])
def test_resonators_are_world_pendulums_seen_from_the_body(kind):
    motion = synthesize(kind, seconds=3.0, seed=3)
    got = with_memory(motion_features(motion), motion.fps, RESONATING)
    assert (
        got.shape
        == (motion.num_frames, feature_width(RESONATING))
        == (motion.num_frames, FEATURE_DIM + 8 * MEMORY_WIDTH)
    )
    for i, hz in enumerate(RESONATING.resonator_hz):
        for j, want in enumerate(world_resonator(motion, hz, RESONATING.damping)):
            row = 2 + 2 * i + j  # after the two averages: w x, then q, per resonator
            cols = slice(FEATURE_DIM + row * MEMORY_WIDTH, FEATURE_DIM + (row + 1) * MEMORY_WIDTH - 1)
            assert np.abs(got[:, cols] - want).max() <= 1e-4 * max(1.0, np.abs(want).max())


@pytest.mark.parametrize("drive_hz", [0.5, 1.0, 2.0])
def test_a_resonator_answers_a_swaying_body_as_a_damped_pendulum(drive_hz):
    """A body swaying sideways, u = sin(2 pi f t), drives the bob to the steady amplitude of
    x'' + 2 zeta w x' + w^2 x = -u': |w x| = w s / |w^2 - s^2 + 2i zeta w s| with s = 2 pi f."""
    fps, hz, damping = 30.0, 1.0, 0.3
    t = np.arange(int(12 * fps)) / fps
    f = np.zeros((len(t), FEATURE_DIM), np.float32)
    f[:, 120] = np.sin(2 * np.pi * drive_hz * t)  # the root's sideways velocity; no turning
    got = with_memory(f, fps, MemorySettings((), (hz,), damping))
    w, s = 2 * np.pi * hz, 2 * np.pi * drive_hz
    settled = got[len(t) // 2 :, FEATURE_DIM + 60]  # w x of the root's sideways velocity, after 6 s
    want = w * s / abs(w * w - s * s + 2j * damping * w * s)
    assert abs(settled.max() - want) <= 0.03 * want


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
@pytest.mark.parametrize("memory", [(0.5, 1.5), RESONATING, CLOCKED, HELD])
def test_memory_is_invariant_to_translation_and_vertical_rotation(kind, memory):
    motion = synthesize(kind, seconds=2.0, seed=7)
    base = with_memory(motion_features(motion), motion.fps, memory)
    for yaw, shift in ((2.5, [0.0, 0.0, 0.0]), (-1.1, [-12.0, 0.0, 40.0])):
        moved = transformed(motion, yaw, shift)
        assert np.abs(with_memory(motion_features(moved), moved.fps, memory) - base).max() <= 1e-4 * max(
            1.0, np.abs(base).max()
        )


@pytest.mark.parametrize("spec", [(0.5, 1.5), RESONATING, CLOCKED, HELD])
def test_stepping_frame_by_frame_equals_the_clip_and_characters_are_independent(spec):
    clips = [
        motion_features(held_still(synthesize(kind, seconds=2.0, seed=5), 30))[-60:]  # moving, then still
        for kind in ("walk_curve", "spin")
    ]
    fps = 30.0
    memory = MotionMemory(spec, fps)
    state = memory.start(np.stack([c[0] for c in clips]))
    rows = [memory.values(state)]
    for t in range(1, len(clips[0])):
        state = memory.step(state, np.stack([c[t] for c in clips]))
        rows.append(memory.values(state))
    stepped = np.stack(rows, 1)  # (2 characters, T, 64 rows)
    for i, clip in enumerate(clips):
        want = with_memory(clip, fps, spec)[:, FEATURE_DIM:]
        assert np.abs(stepped[i] - want).max() <= 1e-5 * max(1.0, np.abs(want).max())


def test_no_time_constants_leaves_the_features_and_bad_ones_are_refused():
    f = motion_features(synthesize("walk", seconds=1.0, seed=0))
    assert with_memory(f, 30.0, ()) is f and feature_width(()) == FEATURE_DIM
    for bad in ((0.0,), (-1.0,), (float("nan"),)):
        with pytest.raises(ValueError, match="positive seconds"):
            check_memory_seconds(bad)
        with pytest.raises(ValueError, match="resonator frequencies must be positive hertz"):
            MemorySettings((0.5,), bad)
    for damping in (0.0, 1.0, 2.0, float("nan")):
        with pytest.raises(ValueError, match="damping"):
            MemorySettings((), (1.0,), damping)


# the stillness clock's known answers: the feature joints' mean speed a frame (m/s), and tau in frames
# (1 / fps each): the start reads LONG_STILL_S, a reset over 0.15, a full count under 0.05, half a
# count at 0.10, a tenth (but no reset) at 0.14
CLOCK_SPEEDS = [0.3, 0.2, 0.0, 0.0, 0.1, 0.1, 0.04, 0.14, 0.2, 0.0]
CLOCK_FRAMES = [None, 0.0, 1.0, 2.0, 2.5, 3.0, 4.0, 4.1, 0.0, 1.0]


def features_at_speeds(speeds) -> np.ndarray:
    """(T, 124) features whose every feature joint moves at ``speeds[t]`` (m/s), each in its own
    direction; everything else zero."""
    f = np.zeros((len(speeds), FEATURE_DIM), np.float32)
    directions = rotation_about_y(np.linspace(0.0, 3.0, 20)) @ np.array([1.0, 0.0, 0.0])  # (20, 3)
    f[:, 60:120] = (np.asarray(speeds)[:, None, None] * directions[None]).reshape(len(speeds), 60)
    return f


def expected_clock(fps: float) -> np.ndarray:
    return np.array([LONG_STILL_S if k is None else k / fps for k in CLOCK_FRAMES])


@pytest.mark.parametrize("fps", [30.0, 24.0])
def test_the_stillness_clock_resets_counts_and_slows_as_the_known_answers_say(fps):
    f, spec = features_at_speeds(CLOCK_SPEEDS), MemorySettings((0.5,), (1.0,), still_seconds=(1.0, 4.0))
    tau = expected_clock(fps)
    np.testing.assert_allclose(still_clock(f, fps), tau, rtol=1e-6)  # float32 speeds
    want = np.exp(-tau[:, None] / np.array([1.0, 4.0]))
    np.testing.assert_allclose(with_memory(f, fps, spec)[:, -2:], want, rtol=1e-6, atol=1e-30)
    memory = MotionMemory(spec, fps)  # the stream's step, one character started three frames late
    states, rows = [None, None], []
    for t in range(len(f)):
        frame = np.stack([f[t], f[max(t - 3, 0)]])
        states = list(
            memory.advance([s if t else None for s in states[:1]] + [states[1] if t > 3 else None], frame)
        )
        rows.append(memory.values(np.stack(states))[:, -2:])
    np.testing.assert_allclose(np.stack(rows)[:, 0], want, rtol=1e-6, atol=1e-30)
    np.testing.assert_allclose(np.stack(rows)[3:, 1], want[: len(f) - 3], rtol=1e-6, atol=1e-30)
    capped = clock_step(np.array([LONG_STILL_S - 1e-3]), f[2:3], fps)
    assert capped[0] == LONG_STILL_S  # the clock never passes its start


def test_the_stillness_clock_counts_the_seconds_since_a_real_stop():
    walk = synthesize("walk", seconds=2.0, seed=3)
    held = held_still(walk, 90)  # then 3 s standing
    fps, spec = held.fps, MemorySettings(still_seconds=(1.0, 4.0))
    got = with_memory(motion_features(held), fps, spec)[:, FEATURE_DIM:]
    assert got.shape == (held.num_frames, 2) and feature_width(spec) == FEATURE_DIM + 2
    np.testing.assert_array_equal(got[0], 0.0)  # the start: the garment at rest (exp(-1000 / s))
    np.testing.assert_array_equal(got[1 : walk.num_frames - 1], 1.0)  # a walk never reads as standing
    # frame walk.num_frames is the first with zero velocity: tau = 1 / fps there, k / fps k frames on
    tau = np.arange(1, 91) / fps
    np.testing.assert_allclose(
        got[walk.num_frames :], np.exp(-tau[:, None] / np.array([1.0, 4.0])), rtol=1e-5
    )
    with pytest.raises(ValueError, match="stillness time constants must be positive"):
        MemorySettings(still_seconds=(0.0,))


def test_held_averages_average_the_moving_time_in_the_world_and_keep_it_through_a_stop():
    walk = synthesize("walk_curve", seconds=2.0, seed=4)
    motion = held_still(walk, 60)  # then 2 s standing
    features = motion_features(motion)
    got = with_memory(features, motion.fps, HELD)
    held = got[:, FEATURE_DIM + 3 * MEMORY_WIDTH : FEATURE_DIM + 5 * MEMORY_WIDTH].reshape(-1, 2, 64)
    assert got.shape[1] == feature_width(HELD) == FEATURE_DIM + 5 * MEMORY_WIDTH + 1
    # the long way: world velocities averaged in the world at a factor each frame's speed sets (the
    # feature joints' mean speed, the same in any frame), turned into each frame's body frame
    v, heading = world_velocities(motion)
    speed = np.linalg.norm(v[:, :20], axis=-1).mean(-1)
    np.testing.assert_allclose(moving_fraction(features), np.clip((speed - 0.05) / 0.1, 0, 1), atol=1e-5)
    for i, seconds in enumerate(HELD.held_seconds):
        hold = np.exp(-np.clip((speed - 0.05) / 0.1, 0, 1) / (motion.fps * seconds))
        avg, want = v[0], []
        for t in range(len(v)):
            avg = avg if t == 0 else hold[t] * avg + (1 - hold[t]) * v[t]
            want.append(avg @ heading[t])
        want = np.array(want).reshape(len(v), -1)
        np.testing.assert_allclose(held[:, i, :-1], want, atol=1e-4 * np.abs(want).max())
    # standing: the held averages keep the walk's last values, where the plain average forgets it
    stop = walk.num_frames  # the first frame with no velocity at all
    np.testing.assert_allclose(held[stop:], np.repeat(held[stop - 1 : stop], len(held) - stop, 0), atol=1e-6)
    assert np.abs(held[-1, 1, :-1]).max() > 0.3  # m/s: the walk, remembered
    plain = got[:, FEATURE_DIM : FEATURE_DIM + MEMORY_WIDTH]
    assert np.abs(plain[-1]).max() < 0.03 * np.abs(plain[stop - 1]).max()  # exp(-60 / 15)
    with pytest.raises(ValueError, match="held time constants must be positive"):
        MemorySettings(held_seconds=(0.0,))
