"""A Motion's values are checked where they enter and cannot change after (issue 48, reproducers
6 and 7): frame rates outside 1-1000, a pelvis beyond 10 km, edits in place."""

import numpy as np
import pytest

from hrr_garment.errors import MotionError
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.synth import synthesize


@pytest.fixture
def walk() -> Motion:
    return synthesize("walk", 1.0, seed=0)


@pytest.mark.parametrize("fps", [1e-300, 0.5, 1e300, float("nan"), True, "30"])
def test_an_impossible_frame_rate_is_refused_by_name(walk, fps):
    with pytest.raises(MotionError, match="frame rate"):
        Motion(walk.local_rotations, walk.root_translation, fps=fps)


@pytest.mark.parametrize("reach", [1e5, 1e30, 1e39])
def test_a_pelvis_far_beyond_any_scene_is_refused(walk, reach):
    root = walk.root_translation.copy()
    root[3, 0] = reach
    with pytest.raises(MotionError, match="move the clip nearer the origin"):
        Motion(walk.local_rotations, root, fps=walk.fps)


def test_a_motion_cannot_be_changed_after_it_was_checked(walk):
    with pytest.raises(ValueError, match="read-only"):
        walk.root_translation[0, 0] = 1e39
    with pytest.raises(ValueError, match="read-only"):
        walk.local_rotations[0, 0] = np.nan
    rotations = walk.local_rotations.copy()  # the caller's own arrays stay writable
    again = Motion(rotations, walk.root_translation, fps=walk.fps)
    rotations[0, 0] = 0.0
    assert rotations.flags.writeable and not again.local_rotations.flags.writeable


def test_a_motion_whose_arrays_its_caller_changed_is_checked_again_when_animated(trained, walk):
    from hrr_garment.inference.animator import Animator

    rotations = walk.local_rotations.copy()
    motion = Motion(rotations, walk.root_translation, fps=walk.fps)
    rotations[5, 3] = np.nan  # through the caller's own array, under the Motion's read-only view
    with pytest.raises(MotionError, match="non-finite values in 1 frame"):
        Animator.load(trained[0] / "model").animate(motion)


@pytest.mark.parametrize(
    "change, phrase",
    [
        (
            lambda r: r * 1000,
            "joint pelvis is not a rotation matrix",
        ),  # "matrices" scaled by 1000 (reproducer 13)
        (lambda r: r * np.diag([-1.0, 1.0, 1.0]), "a scale, a reflection or zeros"),
        (lambda r: np.zeros_like(r), "not a rotation matrix"),
    ],
)
def test_a_local_rotation_that_is_no_rotation_is_refused(walk, change, phrase):
    rot = walk.local_rotations.copy()
    rot[4, 0] = change(rot[4, 0])
    with pytest.raises(
        MotionError, match=f"frame 4.*{phrase}" if "joint" not in phrase else f"frame 4, {phrase}"
    ):
        Motion(rot, walk.root_translation, fps=walk.fps)


@pytest.mark.parametrize("which", ["rotations", "root"])
@pytest.mark.parametrize("dtype", [np.complex128, np.bool_, np.str_])
def test_values_that_are_not_real_numbers_are_refused(walk, which, dtype):
    """Complex values were cast with a warning (the imaginary part dropped), text parsed as numbers."""
    rot, root = walk.local_rotations, walk.root_translation
    if which == "rotations":
        rot = rot.astype(dtype)
    else:
        root = root.astype(dtype)
    with pytest.raises(MotionError, match="expected real numbers"):
        Motion(rot, root, fps=walk.fps)
