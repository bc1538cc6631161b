"""Motion composed from parts of clips: one clip's upper body on another's legs, one arm late, a
clip backward."""

import numpy as np
import pytest

from hrr_garment.motion.compose import (
    ARM_JOINTS,
    UPPER_BODY,
    arm_delayed,
    descendants,
    played_backward,
    spliced,
)
from hrr_garment.motion.skeleton import JOINT_INDEX, JOINT_NAMES
from hrr_garment.motion.synth import synthesize


def test_the_upper_body_is_the_spine_and_everything_above():
    assert {JOINT_NAMES[j] for j in UPPER_BODY} == {
        "spine1",
        "spine2",
        "spine3",
        "neck",
        "head",
        "l_collar",
        "r_collar",
        "l_shoulder",
        "r_shoulder",
        "l_elbow",
        "r_elbow",
        "l_wrist",
        "r_wrist",
    }
    assert {JOINT_NAMES[j] for j in ARM_JOINTS["l"]} == {"l_collar", "l_shoulder", "l_elbow", "l_wrist"}
    assert descendants("l_knee") == (JOINT_INDEX["l_knee"], JOINT_INDEX["l_ankle"], JOINT_INDEX["l_foot"])


def test_a_splice_keeps_the_legs_and_takes_the_upper_body():
    legs, arms = synthesize("run", 2.0, seed=1), synthesize("dance", 3.0, seed=2)
    out = spliced(legs, arms)
    assert out.num_frames == legs.num_frames
    lower = [j for j in range(len(JOINT_NAMES)) if j not in UPPER_BODY]
    # the root and the legs move exactly as the legs' clip: the feet stay where it put them
    np.testing.assert_allclose(out.joint_positions[:, lower], legs.joint_positions[:, lower], atol=1e-6)
    np.testing.assert_array_equal(
        out.local_rotations[:, list(UPPER_BODY)], arms.local_rotations[: legs.num_frames, list(UPPER_BODY)]
    )
    # the arms ride on the legs' pelvis: the wrist relative to the pelvis is the upper clip's,
    # turned by the pelvis
    wrist, pelvis = JOINT_INDEX["l_wrist"], JOINT_INDEX["pelvis"]

    def in_pelvis_frame(m):
        rel = m.joint_positions[:, wrist] - m.joint_positions[:, pelvis]
        return np.einsum("tji,tj->ti", m.global_rotations[:, pelvis], rel)

    np.testing.assert_allclose(in_pelvis_frame(out), in_pelvis_frame(arms)[: legs.num_frames], atol=1e-5)
    with pytest.raises(ValueError, match="shorter"):
        spliced(arms, legs)


def test_an_arm_played_late():
    clip = synthesize("dance", 2.0, seed=0)
    late = arm_delayed(clip, "r", 5)
    arm = list(ARM_JOINTS["r"])
    np.testing.assert_array_equal(late.local_rotations[5:, arm], clip.local_rotations[:-5, arm])
    np.testing.assert_array_equal(
        late.local_rotations[:5, arm], np.repeat(clip.local_rotations[:1, arm], 5, axis=0)
    )
    others = [j for j in range(len(JOINT_NAMES)) if j not in arm]
    np.testing.assert_array_equal(late.local_rotations[:, others], clip.local_rotations[:, others])
    assert (
        np.abs(
            late.joint_positions[:, JOINT_INDEX["r_wrist"]] - clip.joint_positions[:, JOINT_INDEX["r_wrist"]]
        ).max()
        > 0.01
    )
    np.testing.assert_array_equal(arm_delayed(clip, "l", 0).local_rotations, clip.local_rotations)
    with pytest.raises(ValueError):
        arm_delayed(clip, "left", 3)


def test_a_walk_played_backward_walks_backward():
    walk = synthesize("walk", 2.0, seed=0)
    back = played_backward(walk)
    assert back.num_frames == walk.num_frames and back.fps == walk.fps
    # every pose is the capture's own, in reverse order, so the joints retrace their path
    np.testing.assert_allclose(back.joint_positions, walk.joint_positions[::-1], atol=1e-6)

    # the pelvis travels the other way: against the direction the body faces (its root's forward axis, +z)
    def forward_share(motion):
        step = np.diff(motion.root_translation, axis=0)
        return (
            np.einsum("ti,ti->t", step, motion.global_rotations[1:, JOINT_INDEX["pelvis"], :, 2]) > 0
        ).mean()

    assert forward_share(walk) > 0.9 and forward_share(back) < 0.1
    np.testing.assert_array_equal(
        played_backward(back).local_rotations, walk.local_rotations
    )  # twice: the clip
