"""New motion from the parts of captured motion: one clip's upper body on another's legs, one arm
played late against the rest, and a clip played backward.

A library of a few hundred clips covers a few dozen contents (walk, wave, bow, ...); a game combines
them: a character waves while it walks, carries something while it turns. The cloth of a dress
answers mostly to the legs and the hips, but the arms swing and lift it at the sides, so a model
that saw every upper body only over its own legs meets a new combination as motion it has never
seen. :func:`spliced` makes such combinations for the simulator (issue 50: augmentation toward new
contents, not only new speeds). A clip played backward is a content of its own: a walk becomes a
walk backward, a sit-down a stand-up (:func:`played_backward`). The first two edits keep the root
and the legs of one clip whole, so the feet stay where the capture put them; the caller checks the
result for limbs through the body (:mod:`hrr_garment.body.self_contact`) before it is simulated.
"""

from __future__ import annotations

import numpy as np

from .motion import Motion
from .skeleton import JOINT_INDEX, PARENTS


def descendants(joint: str) -> tuple[int, ...]:
    """The joint named ``joint`` and every joint below it in the canonical skeleton, by index."""
    below = [JOINT_INDEX[joint]]
    for j, parent in enumerate(PARENTS):  # parents precede their children in the canonical order
        if parent in below:
            below.append(j)
    return tuple(below)


UPPER_BODY = descendants("spine1")  # the spine, neck, head, collars and arms
ARM_JOINTS = {side: descendants(f"{side}_collar") for side in ("l", "r")}


def spliced(lower: Motion, upper: Motion) -> Motion:
    """``lower``'s root and legs with ``upper``'s spine, head and arms (their rotations relative to
    the pelvis, so the upper body turns with the hips it now stands on). Both clips must have the
    same frame rate; the result has ``lower``'s length, and ``upper`` must be at least that long."""
    if lower.fps != upper.fps:
        raise ValueError(f"the clips' frame rates differ: {lower.fps:g} and {upper.fps:g} frames/s")
    if upper.num_frames < lower.num_frames:
        raise ValueError(
            f"the upper body's clip is shorter ({upper.num_frames} frames) than the legs' "
            f"({lower.num_frames})"
        )
    local = np.array(lower.local_rotations)
    joints = list(UPPER_BODY)
    local[:, joints] = upper.local_rotations[: lower.num_frames, joints]
    return _edited(lower, local, lower.root_translation, f" + upper body of {upper.source}")


def arm_delayed(motion: Motion, side: str, frames: int) -> Motion:
    """``motion`` with one arm (``side`` "l" or "r": collar to wrist) ``frames`` frames late against
    the rest of the body (its first pose held at the start): a phase offset between the arms."""
    if side not in ARM_JOINTS:
        raise ValueError(f"side must be 'l' or 'r', got {side!r}")
    if frames < 0:
        raise ValueError(f"the delay must be zero or more frames, got {frames}")
    local = np.array(motion.local_rotations)
    joints = list(ARM_JOINTS[side])
    source = np.clip(np.arange(motion.num_frames) - frames, 0, None)
    local[:, joints] = motion.local_rotations[source][:, joints]
    return _edited(motion, local, motion.root_translation, f" ({side} arm {frames} frames late)")


def played_backward(motion: Motion) -> Motion:
    """``motion`` with its frames in reverse order: every pose is the capture's own (so no limb passes
    through the body that did not in the capture), the root travels the same path the other way.
    The garment is simulated forward on it, so its cloth answers to the reversed motion as cloth
    does, not as the capture's cloth played back."""
    local, root = motion.local_rotations[::-1].copy(), motion.root_translation[::-1].copy()
    return _edited(motion, local, root, " (played backward)")


def held_still(motion: Motion, frames: int) -> Motion:
    """``motion`` then its last pose held ``frames`` more frames: the body stops dead and stands, as a
    game's character does when its animation ends or cuts to a still pose."""
    idx = np.r_[np.arange(motion.num_frames), np.full(frames, motion.num_frames - 1)]
    return _edited(
        motion, motion.local_rotations[idx], motion.root_translation[idx], f" (then held {frames} frames)"
    )


def _edited(motion: Motion, local_rotations: np.ndarray, root_translation: np.ndarray, what: str) -> Motion:
    """New frames of ``motion``'s skeleton and source, the edit ``what`` appended to its source (the
    poses are the capture's own, checked when it was read)."""
    return Motion(
        local_rotations,
        root_translation,
        motion.fps,
        source=f"{motion.source}{what}",
        source_skeleton=motion.source_skeleton,
        source_height_m=motion.source_height_m,
        skeleton=motion.skeleton,
        check_rotations=False,
    )
