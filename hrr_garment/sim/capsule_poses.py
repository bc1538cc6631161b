"""The capsule body's poses as the simulator's scene moves its kinematic bodies: each capsule's centre
and rotation frame by frame, their interpolation within a frame, and which capsules are the arms
(numpy only: what to simulate is decided without newton, :mod:`.scene` talks to it)."""

from __future__ import annotations

import numpy as np

from ..body.capsules import BodyModel
from ..motion.motion import Motion
from ..motion.rotations import matrix_to_quat, rotation_between

ARMS_OFF_CAPSULES = ("upper_arm", "forearm", "hand")  # taken off the cloth in the simulator's last retries


def arms_off_capsules(body: BodyModel) -> list[int]:
    """Indices into ``body.capsules`` of the capsules the arms-off retries take off the cloth."""
    return [
        c
        for c, capsule in enumerate(body.capsules)
        if capsule.name.endswith(tuple(f"_{p}" for p in ARMS_OFF_CAPSULES))
    ]


def capsule_transforms(motion: Motion, body: BodyModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame and capsule: centre (T, C, 3), quaternion (T, C, 4) as x, y, z, w rotating +Z onto
    the capsule axis, and the half length of the axis (C,)."""
    joint_idx = [motion.skeleton.names.index(c.joint) for c in body.capsules]
    a_loc = np.array([c.a for c in body.capsules])
    b_loc = np.array([c.b for c in body.capsules])
    axis = b_loc - a_loc
    half = 0.5 * np.linalg.norm(axis, axis=1)
    align = rotation_between(np.broadcast_to([0.0, 0.0, 1.0], axis.shape), axis)  # (C, 3, 3) in joint frame
    rot = motion.global_rotations[:, joint_idx].astype(np.float64) @ align[None]
    centre = motion.joint_positions[:, joint_idx] + np.einsum(
        "tcij,cj->tci", motion.global_rotations[:, joint_idx], 0.5 * (a_loc + b_loc)
    )
    q = matrix_to_quat(rot)  # w, x, y, z
    return centre, np.concatenate([q[..., 1:], q[..., :1]], -1), half


def nlerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    """Quaternions (..., 4) normalised-linearly interpolated from ``q0`` to ``q1`` at ``t`` (the
    shorter way round): the capsules' rotation within a frame."""
    q1 = np.where(((q0 * q1).sum(-1, keepdims=True) < 0), -q1, q1)
    q = (1 - t) * q0 + t * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)
