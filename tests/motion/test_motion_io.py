"""Real mocap, BVH variants, AMASS and native npz, resampling."""

import numpy as np
import pytest

from hrr_garment import (
    load_motion,
    motion_features,
    save_amass,
    save_motion,
    synthesize,
)
from hrr_garment.motion.bvh import read_bvh
from hrr_garment.motion.bvh_write import BvhStyle, write_bvh
from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS


@pytest.mark.parametrize("name", ["02_01", "131_01", "131_03"])
def test_cmu_clips_load_and_retarget(cmu_motions, name):
    motion = cmu_motions[name]
    assert motion.source_skeleton == ("cmu" if name == "02_01" else "cmu_max")
    assert motion.fps == 30.0
    assert 1.55 <= motion.source_height_m <= 1.95
    assert abs(motion.lowest_foot_height().mean()) < 0.05
    feats = motion_features(motion)
    assert feats.shape == (motion.num_frames, 124) and np.isfinite(feats).all()
    if name in ("02_01", "131_01"):  # the walks
        assert motion.summary()["root_displacement_m"] > 1.0


def test_cmu_frame_counts_follow_resampling(mocap_dir, cmu_motions):
    clip = read_bvh(mocap_dir / "cmu" / "131_03.bvh")
    assert clip.num_frames == 1102
    duration = (clip.num_frames - 1) * clip.frame_time
    assert cmu_motions["131_03"].num_frames == int(np.floor(duration * 30 + 1e-6)) + 1


def _write(motion, path, **kw):
    write_bvh(
        path,
        list(JOINT_NAMES),
        list(PARENTS),
        CANONICAL.offsets,
        motion.local_rotations.astype(np.float64),
        motion.root_translation.astype(np.float64),
        1.0 / motion.fps,
        BvhStyle(**kw),
    )


def test_bvh_variants_give_identical_features(tmp_path, rng):
    motion = synthesize("dance", seconds=3.0, seed=4)
    plain = tmp_path / "plain.bvh"
    variant = tmp_path / "variant.bvh"
    _write(motion, plain)
    orders = [str(rng.choice(["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])) for _ in JOINT_NAMES]
    _write(motion, variant, orders=orders, positions_on_all_joints=True, unit_scale=100.0)
    text = variant.read_text().replace("\n", "\n\n", 5)  # blank lines are allowed
    variant.write_text(text)
    a, b = load_motion(plain), load_motion(variant)
    assert b.source_height_m == pytest.approx(a.source_height_m, rel=1e-6)
    fa, fb = motion_features(a), motion_features(b)
    assert np.abs(fa - fb).max() <= 1e-4
    assert np.abs(fa - motion_features(motion)).max() <= 1e-4  # and equal to the original motion


def test_bvh_resampling_120fps_is_every_fourth_frame_low_pass_filtered(tmp_path):
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.resample import resample_linear, resample_rotations, resample_times

    fast = synthesize("walk", seconds=2.0, seed=3)
    # Upsample by writing every frame 4 times slower is not possible; instead treat the clip as 120 fps.
    path = tmp_path / "fast.bvh"
    write_bvh(
        path,
        list(JOINT_NAMES),
        list(PARENTS),
        CANONICAL.offsets,
        fast.local_rotations.astype(np.float64),
        fast.root_translation.astype(np.float64),
        1.0 / 120.0,
    )
    slow = load_motion(path, ground=False)
    assert slow.num_frames == (fast.num_frames - 1) // 4 + 1
    # every fourth frame, each averaged over the 120 fps frames within one 30 fps frame of it (the
    # anti-alias filter: motion/resample.py), not the bare fourth frames
    frames = resample_times(fast.num_frames, 120.0, 30.0)
    filtered = Motion(
        resample_rotations(fast.local_rotations.astype(np.float64), frames, 4.0),
        resample_linear(fast.root_translation.astype(np.float64), frames, 4.0),
        30.0,
    )
    np.testing.assert_allclose(slow.joint_positions, filtered.joint_positions, atol=1e-4)
    assert np.abs(slow.joint_positions - fast.joint_positions[::4]).max() > 1e-3  # it did filter


def test_resampling_slerps_between_frames(tmp_path):
    from hrr_garment.motion.io import resample_motion
    from hrr_garment.motion.motion import Motion

    base = synthesize("walk", seconds=2.0, seed=0)
    half = Motion(base.local_rotations[::2], base.root_translation[::2], fps=15.0)
    up = resample_motion(half, 30.0)
    assert up.num_frames == (half.num_frames - 1) * 2 + 1
    np.testing.assert_allclose(up.local_rotations[::2], half.local_rotations, atol=1e-6)
    # Each in-between frame is the geodesic midpoint: half the rotation from its neighbours.
    from hrr_garment.motion.rotations import matrix_to_axis_angle

    rots = up.local_rotations.astype(np.float64)
    prev, mid, nxt = rots[0:-2:2], rots[1:-1:2], rots[2::2]
    first = np.linalg.norm(matrix_to_axis_angle(np.swapaxes(prev, -1, -2) @ mid), axis=-1)
    whole = np.linalg.norm(matrix_to_axis_angle(np.swapaxes(prev, -1, -2) @ nxt), axis=-1)
    np.testing.assert_allclose(first, 0.5 * whole, atol=1e-5)
    np.testing.assert_allclose(
        up.root_translation[1::2], 0.5 * (half.root_translation[:-1] + half.root_translation[1:]), atol=1e-6
    )


@pytest.mark.parametrize("width", [72, 156, 165])
def test_amass_round_trip(tmp_path, width):
    motion = synthesize("walk_curve", seconds=3.0, seed=2)
    path = tmp_path / "amass.npz"
    save_amass(motion, path, width=width)
    with np.load(path) as npz:
        assert npz["poses"].shape == (motion.num_frames, width)
        # Z up: the pelvis height is the third coordinate of trans.
        np.testing.assert_allclose(npz["trans"][:, 2], motion.root_translation[:, 1], atol=1e-6)
    back = load_motion(path)
    assert back.source_skeleton == {72: "smpl", 156: "smplh", 165: "smplx"}[width]
    np.testing.assert_allclose(back.local_rotations, motion.local_rotations, atol=1e-5)
    np.testing.assert_allclose(back.root_translation, motion.root_translation, atol=1e-4)


def test_amass_frame_rate_key_variant_and_resampling(tmp_path):
    motion = synthesize("walk", seconds=2.0, seed=1)
    path = tmp_path / "a.npz"
    save_amass(motion, path)
    with np.load(path) as npz:
        data = dict(npz)
    data["mocap_frame_rate"] = np.float64(60.0)
    del data["mocap_framerate"]
    np.savez(tmp_path / "b.npz", **data)
    back = load_motion(tmp_path / "b.npz")
    assert back.num_frames == (motion.num_frames - 1) // 2 + 1


def test_native_round_trip(tmp_path):
    motion = synthesize("hop", seconds=2.0, seed=5)
    path = tmp_path / "m.npz"
    save_motion(motion, path)
    back = load_motion(path)
    np.testing.assert_array_equal(back.local_rotations, motion.local_rotations)
    np.testing.assert_array_equal(back.root_translation, motion.root_translation)
    assert back.source == motion.source and back.fps == motion.fps


def test_atomic_writes_get_ordinary_permissions(tmp_path):
    import os
    import stat

    from hrr_garment.io_utils import atomic_write_text

    umask = os.umask(0o022)
    try:
        path = tmp_path / "out.txt"
        atomic_write_text(path, "x")
        assert stat.S_IMODE(path.stat().st_mode) == 0o644
    finally:
        os.umask(umask)


def test_strict_json_writes_non_finite_numbers_as_null():
    import json

    from hrr_garment.io_utils import strict_json

    value = {
        "a": float("nan"),
        "b": [np.float32(np.inf), np.float64(1.5), np.int64(3)],
        "c": (np.bool_(True), "x"),
    }
    text = strict_json(value)
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text) == {"a": None, "b": [None, 1.5, 3], "c": [True, "x"]}


def test_concatenate_reuses_forward_kinematics_exactly():
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.synth import synthesize

    m = synthesize("dance", 0.5, seed=2)
    a, b = m.slice(0, 4), m.slice(4, m.num_frames)
    a.joint_positions, b.joint_positions  # noqa: B018 - computed before concatenating
    joined = Motion.concatenate([a, b])
    assert "_fk" in joined.__dict__  # reused, not recomputed
    fresh = Motion.concatenate([m.slice(0, 4), m.slice(4, m.num_frames)])
    assert "_fk" not in fresh.__dict__
    for x, y, z in zip(joined._fk, fresh._fk, m._fk):
        assert np.array_equal(x, y) and np.array_equal(y, z)


def test_an_npz_naming_a_compression_zipfile_lacks_is_refused(tmp_path):
    """Found by tools/fuzz.py (issue 88's run, case 1222): damaged bytes that name an unknown
    compression method were a NotImplementedError traceback."""
    from hrr_garment.errors import MotionError

    path = tmp_path / "clip.npz"
    save_motion(synthesize("walk", 0.5, seed=0), path)
    data = bytearray(path.read_bytes())
    entry = data.index(b"PK\x01\x02")  # the first member's entry in the central directory
    data[entry + 10 : entry + 12] = (99).to_bytes(2, "little")  # its compression method
    path.write_bytes(bytes(data))
    with pytest.raises(MotionError, match="not a readable npz file"):
        load_motion(path)


def test_a_bvh_of_a_billion_frames_a_second_is_refused_unless_its_rate_is_given(tmp_path):
    """Found by tools/fuzz.py (issue 88's run, case 1537): a frame time of 1e-9 s asked the
    low-pass filter for 98 GiB."""
    from hrr_garment.errors import MotionError

    motion = synthesize("walk", 1.0, seed=0)
    path = tmp_path / "fast.bvh"
    rotations = motion.local_rotations.astype(np.float64)
    write_bvh(
        path, list(JOINT_NAMES), list(PARENTS), CANONICAL.offsets, rotations, motion.root_translation, 1 / 30
    )
    lines = [
        ("Frame Time: 1e-9" if ln.startswith("Frame Time") else ln) for ln in path.read_text().splitlines()
    ]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(MotionError, match="more than 1000: give the capture rate with --fps"):
        load_motion(path)
    assert load_motion(path, source_fps=30.0).num_frames == motion.num_frames
