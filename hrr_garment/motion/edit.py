"""Motion editing as a game's animation system does it: a clip played faster or slower, and one
clip cross-faded into another.

A game rarely plays its library clips as they were captured: it re-times them to match a
character's speed, starts them wherever the state machine enters them, and blends from one into
the next over a few tenths of a second. ``hrr-eval``'s library protocol plays the training clips
again this way (:mod:`hrr_garment.eval.library`); both edits also serve anyone composing motions
for a prototype.
"""

from __future__ import annotations

import numpy as np

from .motion import Motion
from .resample import resample_linear, resample_rotations, resample_times
from .rotations import matrix_to_quat, quat_slerp, quat_to_matrix, rotation_about_y, yaw_of

GROUND = np.array([1.0, 0.0, 1.0])  # keeps the horizontal part of a position


def retimed(motion: Motion, speed: float) -> Motion:
    """``motion`` played ``speed`` times faster (0.9: ten percent slower) at its own frame rate:
    rotations slerped, the root interpolated linearly. The duration becomes (T - 1) / speed frames
    plus one, the first frame is kept."""
    if not (np.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be a positive number, got {speed}")
    if speed == 1.0:
        return motion
    frames = resample_times(motion.num_frames, motion.fps * speed, motion.fps)
    return Motion(
        resample_rotations(motion.local_rotations.astype(np.float64), frames),
        resample_linear(motion.root_translation, frames),
        motion.fps,
        source=motion.source,
        source_skeleton=motion.source_skeleton,
        source_height_m=motion.source_height_m,
        skeleton=motion.skeleton,
        check_rotations=False,
    )  # slerped rotations


def aligned(motion: Motion, heading: float, position: np.ndarray) -> Motion:
    """``motion`` turned about the vertical and moved over the ground so that its first frame's
    pelvis faces ``heading`` (radians about +Y) and stands above ``position`` (its height kept)."""
    turn = rotation_about_y(np.asarray(heading - yaw_of(motion.global_rotations[0, 0]), np.float64))
    local = motion.local_rotations.copy()
    local[:, 0] = turn.astype(np.float32) @ local[:, 0]  # the root joint's rotation is global
    root = motion.root_translation
    moved = (root - root[0] * GROUND) @ turn.T + np.asarray(position, np.float64) * GROUND
    return Motion(
        local,
        moved,
        motion.fps,
        source=motion.source,
        source_skeleton=motion.source_skeleton,
        source_height_m=motion.source_height_m,
        skeleton=motion.skeleton,
    )


def smoothstep_weights(frames: int) -> np.ndarray:
    """(frames,) the second clip's weight over a cross-fade: smoothstep, strictly between 0 and 1,
    so both ends stay in the blend (zero rate of change where it starts and ends)."""
    x = (np.arange(frames) + 1.0) / (frames + 1.0)
    return x * x * (3.0 - 2.0 * x)


def crossfade(first: Motion, second: Motion, frames: int) -> Motion:
    """``first``, then ``second`` entered over the last ``frames`` frames of ``first``.

    ``second`` is first :func:`aligned` to where the blend starts (the pelvis heading and ground
    position of ``first``'s frame T - frames), so the character carries on from where it is; over
    the blend every joint's local rotation slerps and the root moves linearly from ``first`` to
    ``second`` with a smoothstep weight (zero rate of change at both ends). The result has
    len(first) + len(second) - frames frames; a clip cross-faded with its own continuation
    (``first`` = m[:k + n], ``second`` = m[k:]) gives m back."""
    if first.fps != second.fps:
        raise ValueError(f"cannot blend motions at {first.fps:g} and {second.fps:g} fps: retime one first")
    if first.skeleton is not second.skeleton and first.skeleton != second.skeleton:
        raise ValueError("cannot blend motions on different skeletons")
    if not 1 <= frames <= min(first.num_frames, second.num_frames):
        raise ValueError(
            f"a blend of {frames} frames needs both motions at least that long "
            f"({first.num_frames} and {second.num_frames} frames)"
        )
    start = first.num_frames - frames
    second = aligned(second, float(yaw_of(first.global_rotations[start, 0])), first.root_translation[start])
    w = smoothstep_weights(frames)
    qa = matrix_to_quat(first.local_rotations[start:].astype(np.float64))
    qb = matrix_to_quat(second.local_rotations[:frames].astype(np.float64))
    blend_rot = quat_to_matrix(quat_slerp(qa, qb, np.broadcast_to(w[:, None], qa.shape[:-1])))
    blend_root = (1.0 - w[:, None]) * first.root_translation[start:] + w[:, None] * second.root_translation[
        :frames
    ]
    return Motion(
        np.concatenate(
            [first.local_rotations[:start], blend_rot.astype(np.float32), second.local_rotations[frames:]]
        ),
        np.concatenate([first.root_translation[:start], blend_root, second.root_translation[frames:]]),
        first.fps,
        source=first.source,
        source_skeleton=first.source_skeleton,
        source_height_m=first.source_height_m,
        skeleton=first.skeleton,
    )
