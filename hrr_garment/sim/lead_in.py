"""The frames a simulation runs before recording: settle in the rest pose, then blend into the clip.

The garment template is modelled in the rest pose at the origin facing +Z. A sequence starts with
the body in that pose, turned and moved to where the clip starts (so nothing teleports), holds it
while the cloth settles under gravity, eases into the clip's first frame, then plays the clip.
"""

from __future__ import annotations

import numpy as np

from ..motion.motion import Motion
from ..motion.rotations import (
    matrix_to_quat,
    quat_slerp,
    quat_to_matrix,
    rotation_about_y,
    yaw_of,
)
from ..motion.skeleton import REST_PELVIS_HEIGHT


def start_transform(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (3, 3) about Y and translation (3,) placing the rest pose where the clip starts."""
    yaw = float(yaw_of(motion.global_rotations[0, 0]))
    root = motion.root_translation[0]
    return rotation_about_y(np.array(yaw)), np.array([root[0], 0.0, root[2]])


def lead_in_frames(settle_s: float, blend_s: float, fps: float) -> tuple[int, int]:
    """Frames of settling and of blending that :func:`with_lead_in` puts before a clip at ``fps``."""
    return int(round(settle_s * fps)), int(round(blend_s * fps))


def with_lead_in(
    motion: Motion, settle_s: float, blend_s: float, pelvis_height: float = REST_PELVIS_HEIGHT
) -> tuple[Motion, int]:
    """The clip preceded by ``settle_s`` of rest pose and ``blend_s`` of easing into frame 0, on the
    clip's own skeleton; ``pelvis_height``: where its body's pelvis stands in the rest pose (the
    mannequin's by default; a body's own, :attr:`~hrr_garment.body.capsules.BodyModel.pelvis_height`).

    Returns (extended motion, number of lead-in frames); frame ``lead`` of the result is the
    clip's frame 0.
    """
    settle, blend = lead_in_frames(settle_s, blend_s, motion.fps)
    rot_y, shift = start_transform(motion)
    joints = motion.local_rotations.shape[1]
    rest_local = np.broadcast_to(np.eye(3, dtype=np.float32), (joints, 3, 3)).copy()
    rest_local[0] = rot_y
    rest_root = shift + np.array([0.0, pelvis_height, 0.0])
    # Smoothstep easing from the rest pose (t = 0) to the first clip frame (t = 1).
    t = (np.arange(1, blend + 1) / (blend + 1)) if blend else np.zeros(0)
    ease = t * t * (3.0 - 2.0 * t)
    q0, q1 = matrix_to_quat(rest_local), matrix_to_quat(motion.local_rotations[0])
    blend_rot = quat_to_matrix(
        quat_slerp(q0[None], q1[None], np.broadcast_to(ease[:, None], (blend, joints)))
    )
    blend_root = rest_root[None] + ease[:, None] * (motion.root_translation[0] - rest_root)[None]
    local = np.concatenate(
        [np.repeat(rest_local[None], settle, 0), blend_rot.astype(np.float32), motion.local_rotations]
    )
    root = np.concatenate([np.repeat(rest_root[None], settle, 0), blend_root, motion.root_translation])
    extended = Motion(
        local.astype(np.float32),
        root.astype(np.float64),
        motion.fps,
        source=motion.source,
        source_skeleton=motion.source_skeleton,
        source_height_m=motion.source_height_m,
        skeleton=motion.skeleton,
    )
    return extended, settle + blend
