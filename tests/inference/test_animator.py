"""The offline engine (Animator.animate): every mode, excluded sequences, short clips, and the
plausibility check before an animation is saved."""

import math

import numpy as np
import pytest

from hrr_garment.motion.synth import synthesize


@pytest.mark.parametrize("mode", ["hybrid", "regression", "retrieval", "naive-nn"])
def test_every_mode_animates_every_frame(animator, mode):
    motion = synthesize("spin", 1.0, seed=2)
    anim = animator.animate(motion, mode=mode)
    assert anim.vertices.shape == (motion.num_frames, animator.bundle.template.num_vertices, 3)
    assert np.isfinite(anim.vertices).all() and anim.joints.shape == (motion.num_frames, 22, 3)
    assert (
        0 <= anim.entropy.min()
        and anim.entropy.max() <= math.log(animator.bundle.codespace.config.classes) + 1e-5
    )
    if mode == "regression":
        assert anim.retrieved.sum() == 0 and (anim.match == -1).all()
    if mode in ("retrieval", "naive-nn"):
        assert anim.retrieved.all() and (anim.match >= 0).all()


def test_excluding_a_sequence_never_retrieves_it(animator):
    anim = animator.animate(synthesize("walk", 1.0, seed=0), mode="retrieval", exclude_sequence=0)
    assert (anim.match[:, 0] != 0).all()
    for wrong in ("x", -1, 999, 1.5, True):  # not a database sequence index
        with pytest.raises(ValueError, match="exclude_sequence must be a database sequence index"):
            animator.animate(synthesize("walk", 0.5, seed=0), mode="retrieval", exclude_sequence=wrong)


def test_clip_shorter_than_a_window_is_padded(animator):
    anim = animator.animate(synthesize("walk", 0.2, seed=1))  # 6 frames < W = 10
    assert anim.vertices.shape[0] == 6 and np.isfinite(anim.vertices).all()
    assert animator.animate(synthesize("walk", 0.2, seed=1).slice(0, 1)).vertices.shape[0] == 1


@pytest.mark.parametrize("mode", ["regression", "hybrid"])
def test_a_body_standing_still_keeps_its_cloth_still_to_both_ends_of_the_clip(animator, mode):
    """Offline, every frame is the blend of all the windows' positions, the clip's first and last
    frames included (its ends repeated): the cloth of a body that never moves does not move. With
    the clip's own windows alone, the frames within a window of either end took the windows'
    leading or trailing positions only, and drifted (12-19 mm a frame on a trained model)."""
    from hrr_garment.motion.compose import held_still

    still = held_still(synthesize("walk", 0.2, seed=1).slice(0, 1), 39)
    vertices = animator.animate(still, mode=mode, push_out=False).vertices.astype(np.float64)
    moved = np.linalg.norm(np.diff(vertices, axis=0), axis=-1).max()
    assert moved < 1e-5, f"the cloth moved {moved * 1000:.3f} mm between two frames of a still body"


def test_each_frames_diagnostics_are_the_window_centred_on_it(animator):
    """Offline, frame t reports the entropy and match of the window centred on it (window i of the
    clip's covering windows holding frames i - W + 1 .. i), near an end the clip's first or last
    window of its own frames: the ones past the ends hold repeated frames."""
    from hrr_garment.inference.frame_path import FramePath
    from hrr_garment.motion.windows import covering_windows

    motion, w = synthesize("walk", 1.0, seed=0), animator.window
    anim = animator.animate(motion, mode="retrieval", push_out=False)
    windows = np.ascontiguousarray(covering_windows(animator.features(motion), w))
    choice = FramePath(animator, animator.resolve(mode="retrieval")).choose(windows)
    t = np.arange(motion.num_frames)
    centred = np.clip(t - w // 2, 0, motion.num_frames - w) + w - 1
    assert centred[0] == w - 1 and centred[-1] == motion.num_frames - 1  # the clip's first and last windows
    np.testing.assert_allclose(anim.entropy, choice.entropy[centred], rtol=1e-6)
    assert np.array_equal(anim.match, choice.match[centred])


@pytest.mark.parametrize(
    "damage, phrase",
    [
        (
            lambda v: v.__setitem__((3, 5, 0), np.nan),
            r"non-finite vertices on 1 frame\(s\), first at frame 3",
        ),
        (lambda v: v.__setitem__((2, 0, 1), 7.0), "m from the body at frame 2"),
    ],
)
def test_an_absurd_animation_is_refused_and_nothing_is_written(tmp_path, damage, phrase):
    from hrr_garment.errors import InputError
    from hrr_garment.inference.animator import Animation

    motion = synthesize("walk", 0.2, seed=0)
    joints = motion.joint_positions.astype(np.float32)
    vertices = joints[:, :1] + np.zeros((1, 10, 3), np.float32)  # every vertex at the pelvis
    anim = Animation(
        vertices,
        np.array([[0, 1, 2]]),
        30.0,
        np.zeros(len(joints), np.uint8),
        np.zeros(len(joints), np.float32),
        -np.ones((len(joints), 2), np.int32),
        joints,
        "skirt",
        "hash",
        "walk",
    )
    anim.check(tmp_path / "ok.h5")  # a plausible one passes
    damage(anim.vertices)
    with pytest.raises(InputError, match=phrase):
        anim.save(tmp_path / "out.h5")
    assert not list(tmp_path.iterdir())
