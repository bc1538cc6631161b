"""Streaming: a stream and a crowd equal the offline causal animation, frame by frame, whatever joins
and leaves; raw engine poses and source rigs; what a push refuses; bfloat16 crowds."""

import warnings

import numpy as np
import pytest

from hrr_garment.motion.synth import synthesize


@pytest.mark.parametrize("mode", ["hybrid", "regression", "retrieval", "detail", "naive-nn"])
def test_stream_equals_offline_causal(animator, mode):
    motion = synthesize("walk_curve", 1.2, seed=7)
    causal = animator.animate(motion, mode=mode, causal=True)
    stream = animator.stream(mode=mode)
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal.vertices).max() <= 1e-5
    assert len(stream.crowd._characters[0].features) == animator.window  # bounded memory
    stages = {k: np.array(v) for k, v in stream.stage_s.items()}  # per-stage timings cover every push
    assert all(len(v) == motion.num_frames and (v >= 0).all() for v in stages.values())
    assert sum(v.sum() for v in stages.values()) <= np.sum(stream.latency_s) + 1e-9


@pytest.mark.parametrize("mode", ["hybrid", "detail"])  # detail: a fold playhead per character
def test_a_crowd_streamed_together_equals_each_character_streamed_alone(animator, mode):
    """Characters join and leave between frames and come in another order every third frame; each
    one's frames equal its own offline causal animation (which the single stream equals), whatever
    the others in the same push (the crowd's windows slide in place while its keys stay)."""
    clips = {
        "a": synthesize("walk_curve", 1.0, seed=1),
        "b": synthesize("spin", 1.0, seed=2),
        "c": synthesize("dance", 1.0, seed=3),
    }
    alone = {k: animator.animate(m, mode=mode, causal=True).vertices for k, m in clips.items()}
    joins = {"a": 0, "b": 4, "c": 9}  # b joins at frame 4; a leaves after frame 19, c after 24
    leaves = {"a": 20, "b": 30, "c": 25}
    crowd = animator.crowd(mode=mode)
    for frame in range(30):
        present = [k for k in clips if joins[k] <= frame < leaves[k]][:: 1 if frame % 3 else -1]
        for k in set(crowd.characters) - set(present):
            crowd.leave(k)
        poses = {k: clips[k].slice(frame - joins[k], frame - joins[k] + 1) for k in present}
        out = crowd.push_motions(poses)
        assert out.shape == (len(present), animator.bundle.template.num_vertices, 3)
        for row, k in enumerate(present):
            assert np.abs(out[row] - alone[k][frame - joins[k]]).max() <= 1e-5, (k, frame)
    assert crowd.characters == ["b"]
    step = crowd._step  # the native window step takes each frame's gates once, as the frame came
    assert (crowd._windows.gates is not None) == hasattr(step, "frame_gates")
    crowd.leave("b")
    with pytest.raises(KeyError, match="no character 'a'"):
        crowd.leave("a")


@pytest.mark.parametrize("form", ["quaternion", "axis-angle", "matrix"])
def test_raw_poses_stream_like_the_same_clip_from_its_file(animator, tmp_path, form):
    """An engine's arrays (local rotations, root) give what the clip saved to a file and loaded gives."""
    from hrr_garment.motion.io import load_motion, save_motion
    from hrr_garment.motion.rotations import matrix_to_axis_angle, matrix_to_quat

    save_motion(synthesize("walk_curve", 1.0, seed=4), tmp_path / "clip.npz")
    motion = load_motion(tmp_path / "clip.npz")
    expected = animator.animate(motion, causal=True).vertices
    local = motion.local_rotations.astype(np.float64)
    rotations = {
        "quaternion": matrix_to_quat(local)[..., [1, 2, 3, 0]],  # (x, y, z, w), as engines hand them
        "axis-angle": matrix_to_axis_angle(local),
        "matrix": local,
    }[form]
    crowd = animator.crowd()
    two = (
        np.stack([rotations, rotations], 1),
        np.stack([motion.root_translation, motion.root_translation + 3.0], 1),
    )
    for t in range(motion.num_frames):  # two characters: the clip, and the clip 3 m away
        out = crowd.push(two[0][t], two[1][t], keys=["here", "there"])
        assert np.abs(out[0] - expected[t]).max() <= 1e-4 and np.abs(out[1] - 3.0 - expected[t]).max() <= 1e-4
    single = animator.stream()
    assert (
        np.abs(single.push(rotation=rotations[0], root=motion.root_translation[0]) - expected[0]).max()
        <= 1e-4
    )


def test_a_source_rig_streams_like_its_file(animator, tmp_path):
    """Poses on a rig with another joint order, centimetres and a baked roll per joint (Bandai-
    Namco's kind of rig: no standing rest pose), pushed as the BVH has them, give what animating
    the file gives: the same joint map, retargeting, roll and floor."""
    from hrr_garment.motion.bvh import read_bvh
    from hrr_garment.motion.bvh_write import BvhStyle, write_bvh
    from hrr_garment.motion.io import load_motion
    from hrr_garment.motion.rotations import axis_angle_to_matrix, matrix_to_quat
    from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS
    from hrr_garment.motion.stream_rig import StreamRig

    motion = synthesize("dance", 1.0, seed=6)
    roll = axis_angle_to_matrix(np.random.default_rng(0).normal(size=(22, 3)) * 1.5)  # per-joint rig frames
    local = np.empty_like(motion.global_rotations)
    local[:, 0] = motion.global_rotations[:, 0] @ roll[0]
    for j in range(1, 22):
        local[:, j] = roll[PARENTS[j]].T @ motion.local_rotations[:, j].astype(np.float64) @ roll[j]
    offsets = np.stack(
        [roll[PARENTS[j]].T @ CANONICAL.offsets[j] if j else CANONICAL.offsets[j] for j in range(22)]
    )
    order = [
        0,
        3,
        6,
        9,
        12,
        15,
        13,
        16,
        18,
        20,
        14,
        17,
        19,
        21,
        1,
        4,
        7,
        10,
        2,
        5,
        8,
        11,
    ]  # spine first, then limbs
    path = tmp_path / "rig.bvh"
    write_bvh(
        path,
        [JOINT_NAMES[j] for j in order],
        [order.index(PARENTS[j]) if j else -1 for j in order],
        offsets[order],
        local[:, order],
        motion.root_translation,
        1 / 30,
        BvhStyle(unit_scale=100.0),
    )
    expected = animator.animate(load_motion(path), causal=True).vertices
    clip = read_bvh(path)  # what an engine holds each frame: the rig's local rotations, the root in its units
    rig = StreamRig.from_bvh(path)
    assert rig.unit_scale == pytest.approx(0.01) and rig.calibration.roll is not None
    crowd = animator.crowd(rig=rig)
    quats = matrix_to_quat(clip.local_rotations.astype(np.float64))[..., [1, 2, 3, 0]]
    for t in range(clip.num_frames):
        out = crowd.push(quats[t][None], clip.local_translations[t, :1], keys=["hero"])
        assert np.abs(out[0] - expected[t]).max() <= 1e-4, t


@pytest.mark.parametrize(
    "rotations, roots, phrase",
    [
        (np.zeros((2, 21, 4)), np.zeros((2, 3)), r"expected \(N, 22, 4\) quaternions"),
        (np.full((1, 22, 3), np.nan), np.zeros((1, 3)), "rotations are not finite"),
        (np.zeros((1, 22, 4)), np.zeros((1, 3)), "not a rotation"),
        (np.tile(np.eye(3) * 2, (1, 22, 1, 1)), np.zeros((1, 3)), "not a rotation"),
        (np.zeros((1, 22, 3)), np.zeros((2, 3)), r"roots have shape \(2, 3\), expected \(1, 3\)"),
        (np.zeros((1, 22, 3)), np.array([[0.0, np.inf, 0.0]]), "root of pose 0 is not finite"),
        # float64 passes these, float32 vertices cannot hold them (issue 48, reproducer 5)
        (np.zeros((1, 22, 3)), np.array([[1e39, 0.95, 0.0]]), "root of pose 0 is 1e[+]39 m from the origin"),
        (np.zeros((1, 22, 3)), np.array([[1e30, 0.95, 0.0]]), "root of pose 0 is 1e[+]30 m from the origin"),
        (np.full((1, 22, 3), 1e39), np.zeros((1, 3)), "axis-angle of pose 0, joint 0 turns"),
    ],
)
def test_bad_raw_poses_are_refused_clearly(animator, rotations, roots, phrase):
    from hrr_garment.errors import MotionError

    with pytest.raises(MotionError, match=phrase):
        animator.crowd().push(rotations, roots)


def test_a_push_needs_distinct_keys(animator):
    from hrr_garment.errors import InputError

    with pytest.raises(InputError, match="as many distinct keys"):
        animator.crowd().push(np.zeros((2, 22, 3)), np.zeros((2, 3)), keys=["x", "x"])


def test_stream_refuses_an_offline_only_mode(animator):
    with pytest.raises(ValueError, match="direct"):
        animator.stream(mode="direct")


def test_a_bfloat16_crowd_stays_near_the_float32_one(animator):
    """Eight characters (a batch the AMX decoder takes) in bfloat16: the same gate decisions and
    windows, vertices within bfloat16's rounding of the float32 crowd's."""
    from hrr_garment.inference.animator import Animator

    if not animator.decoder.native or not animator.decoder.lib.hrr_amx_ready():
        pytest.skip("no AMX (bfloat16 decoding) on this CPU")
    half = Animator(animator.bundle, precision="bfloat16")
    clips = [
        synthesize(kind, 1.0, seed=i) for i, kind in enumerate(["walk_curve", "spin", "dance", "idle"] * 2)
    ]
    crowds = [a.crowd(push_out=False) for a in (animator, half)]
    error = []
    for t in range(clips[0].num_frames):
        poses = {i: c.slice(t, t + 1) for i, c in enumerate(clips)}
        exact, rounded = (crowd.push_motions(poses) for crowd in crowds)
        error.append(np.linalg.norm(rounded - exact, axis=-1))
    error = np.array(error)
    assert error.mean() <= 2e-4 and error.max() <= 2e-3  # metres


def test_a_teleport_restarts_the_character_with_a_warning(animator):
    """A pelvis 50 m away one frame later (1,500 m/s) is a respawn: the character's garment is
    what a fresh stream gives for that pose, not cloth dragged across the jump (issue 48, 5)."""
    from hrr_garment.errors import TeleportWarning

    clip = synthesize("walk", 1.0, seed=2)
    rot, root = clip.local_rotations, clip.root_translation
    moved = root[10] + np.array([50.0, 0.0, 0.0])
    stream = animator.crowd()
    for t in range(10):
        stream.push(rot[t][None], root[t][None], keys=["npc"])
    with pytest.warns(TeleportWarning, match="'npc': the pelvis moved 50 m in one frame") as caught:
        jumped = stream.push(rot[10][None], moved[None], keys=["npc"])
    assert caught[0].filename == __file__  # the warning points at the user's push
    one = animator.stream()  # a one-character stream warns at its user's line too
    one.push(rotation=rot[9], root=root[9])
    with pytest.warns(TeleportWarning) as caught:
        one.push(rotation=rot[10], root=moved)
    assert caught[0].filename == __file__
    fresh = animator.crowd().push(rot[10][None], moved[None], keys=["npc"])
    np.testing.assert_allclose(jumped, fresh, atol=1e-5)
    assert stream._characters["npc"].frames == 1
    with warnings.catch_warnings():  # walking on from there is no teleport
        warnings.simplefilter("error", TeleportWarning)
        stream.push(rot[11][None], (root[11] + np.array([50.0, 0.0, 0.0]))[None], keys=["npc"])
