import numpy as np
import pytest

from hrr_garment import FeatureStats, MotionError, motion_features, synthesize, windows
from hrr_garment.motion.features import SLICE_T, SLICE_V, SLICE_W
from hrr_garment.motion.frame import body_heading
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.rotations import rotation_about_y
from hrr_garment.motion.skeleton import FEATURE_JOINTS


def transformed(motion: Motion, yaw: float, shift) -> Motion:
    rot = rotation_about_y(np.array(yaw))
    local = motion.local_rotations.astype(np.float64).copy()
    local[:, 0] = rot @ local[:, 0]
    root = motion.root_translation.astype(np.float64) @ rot.T + np.asarray(shift)
    return Motion(local, root, motion.fps)


@pytest.mark.parametrize("kind", ["walk_curve", "spin", "dance"])
def test_invariant_to_translation_and_vertical_rotation(kind):
    motion = synthesize(kind, seconds=2.0, seed=7)
    base = motion_features(motion)
    for yaw, shift in ((0.0, [5.0, 0.0, -3.0]), (2.5, [0.0, 0.0, 0.0]), (-1.1, [-12.0, 0.0, 40.0])):
        assert np.abs(motion_features(transformed(motion, yaw, shift)) - base).max() <= 1e-5


def test_feature_layout_and_velocities_match_finite_differences():
    motion = synthesize("walk", seconds=2.0, seed=1)
    f = motion_features(motion).astype(np.float64)
    assert f.shape == (motion.num_frames, 124) and f.dtype == np.float64
    _, h = body_heading(motion)
    pos = motion.joint_positions[:, list(FEATURE_JOINTS)]
    t = 10
    world_v = (pos[t] - pos[t - 1]) * 30.0
    np.testing.assert_allclose(f[t, SLICE_V].reshape(20, 3), world_v @ h[t], atol=1e-4)
    root_v = (motion.joint_positions[t, 0] - motion.joint_positions[t - 1, 0]) * 30.0
    np.testing.assert_allclose(f[t, SLICE_T], root_v @ h[t], atol=1e-4)
    # walking forward: the root moves along +z of its heading frame at the walking speed
    assert f[:, SLICE_T][:, 2].mean() > 0.5 and abs(f[:, SLICE_T][:, 0].mean()) < 0.05
    yaw = np.unwrap(body_heading(motion)[0])
    np.testing.assert_allclose(f[1:, SLICE_W][:, 0], np.diff(yaw) * 30.0, atol=1e-4)


def test_turning_sign_of_yaw_velocity():
    left = motion_features(synthesize("turn_in_place", seconds=2.0, seed=0, turn_rate=60.0))
    right = motion_features(synthesize("turn_in_place", seconds=2.0, seed=0, turn_rate=-60.0))
    mid = slice(20, 40)
    assert left[mid, SLICE_W].mean() == pytest.approx(np.deg2rad(60.0), rel=0.05)
    assert right[mid, SLICE_W].mean() == pytest.approx(-np.deg2rad(60.0), rel=0.05)


def test_windows_and_standardisation():
    f = motion_features(synthesize("run", seconds=1.0, seed=0))
    w = windows(f, 10)
    assert w.shape == (f.shape[0] - 9, 10, 124)
    np.testing.assert_array_equal(w[3, 0], f[3])
    np.testing.assert_array_equal(w[3, 9], f[12])
    assert windows(f, 10, stride=4).shape[0] == (f.shape[0] - 10) // 4 + 1
    with pytest.raises(MotionError, match="shorter than one window"):
        windows(f[:5], 10, source="clip.bvh")
    stats = FeatureStats.fit([f, 2 * f])
    z = stats.normalize(f)
    np.testing.assert_allclose(stats.denormalize(z), f, atol=1e-4)
    both = stats.normalize(np.concatenate([f, 2 * f]))
    busy = both.std(0) > 0.5
    np.testing.assert_allclose(both.mean(0)[busy], 0.0, atol=1e-4)
    np.testing.assert_allclose(both.std(0)[busy], 1.0, atol=1e-3)
    again = FeatureStats.from_dict(stats.to_dict())
    np.testing.assert_array_equal(again.mean, stats.mean)


@pytest.mark.native
@pytest.mark.parametrize("kind", ["walk_curve", "spin", "dance"])
def test_native_kinematics_and_causal_features_equal_numpy(kind, monkeypatch):
    from hrr_garment import native
    from hrr_garment.motion.features import causal_features
    from hrr_garment.motion.skeleton import forward_kinematics

    lib = native.load_kernel()
    if lib is None:
        pytest.skip("no C compiler: the native kernels are unavailable")
    motion = synthesize(kind, seconds=2.0, seed=5)
    sk = motion.skeleton
    g_rot, g_pos = native.forward_kinematics(
        lib, motion.local_rotations, motion.root_translation, sk.offsets, sk.parents
    )
    want_rot, want_pos = forward_kinematics(
        motion.local_rotations.astype(np.float64),
        motion.root_translation,
        sk.offsets.astype(np.float64),
        sk.parents,
    )
    assert np.abs(g_rot - want_rot).max() < 1e-12 and np.abs(g_pos - want_pos).max() < 1e-12
    got = causal_features(motion)
    monkeypatch.setattr(
        native, "load_kernel", lambda *args, **kwargs: None
    )  # the numpy reference, FK included
    want = causal_features(Motion(motion.local_rotations, motion.root_translation, motion.fps))
    assert got.shape == want.shape == (motion.num_frames, 124)
    assert np.abs(got - want).max() < 1e-5
    assert np.abs(got[0, 60:]).max() == 0  # frame 0 sees only itself: no velocities
    assert np.abs(got[1:] - motion_features(motion)[1:]).max() < 1e-5
