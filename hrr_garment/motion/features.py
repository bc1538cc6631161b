"""Per-frame motion features (paper 3.3; docs/motion.md), offline and causal, and their statistics.

f_t = [r (60); v (60); t (3); w (1)] = 124 values, all in the body frame's orientation at frame t
(rotated by the pelvis yaw only, :func:`~hrr_garment.motion.frame.body_heading`):

* r: global rotation of each of the 20 feature joints, expressed in the body frame, axis-angle;
* v: world velocity of each feature joint, (p_t - p_{t-1}) / dt, rotated into the body frame;
* t: root (pelvis) translation velocity in the body frame;
* w: yaw angular velocity (rad/s), wrapped to (-pi, pi] per frame step.

Offline (:func:`motion_features`), velocities at frame 0 use the first difference (frames 0 and
1), so every frame has a value. Causal (:func:`causal_features`, what a stream sees), frame t uses
frames t-1 and t only, frame 0 itself (zero velocities); the same formulas, in C where compiled
(``hrr_garment/native/features.c``). The features do not change when the whole motion is
translated or rotated about the vertical axis. Windows over them: :mod:`.windows`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import native
from ..errors import MotionError
from .motion import Motion
from .resample import frame_chunks
from .rotations import matrix_to_axis_angle, rotation_about_y, yaw_of
from .skeleton import FEATURE_JOINTS

FEATURE_DIM = 124
# Column slices of the feature vector.
SLICE_R = slice(0, 60)
SLICE_V = slice(60, 120)
SLICE_T = slice(120, 123)
SLICE_W = slice(123, 124)


def _first_difference(x: np.ndarray, fps: float) -> np.ndarray:
    d = np.empty_like(x)
    d[1:] = (x[1:] - x[:-1]) * fps
    d[0] = d[1] if len(x) > 1 else 0.0
    return d


def motion_features(motion: Motion) -> np.ndarray:
    """(T, 124) float32 features of a canonical motion."""
    if motion.num_frames < 2:
        raise MotionError(
            motion.source or "motion", f"needs at least 2 frames for velocities, has {motion.num_frames}"
        )
    chunks = frame_chunks(motion.num_frames)
    if len(chunks) == 1:
        return _features(motion.global_rotations, motion.joint_positions, motion.fps)
    # hours of motion in passes that bound the float64 temporaries; each pass starts one frame
    # early so that its first velocity is the true difference
    feats = np.empty((motion.num_frames, FEATURE_DIM), np.float32)
    for start, stop in chunks:
        first = max(0, start - 1)
        part = motion.slice(first, stop)
        feats[start:stop] = _features(part.global_rotations, part.joint_positions, motion.fps)[
            start - first :
        ]
    return feats


def _features(global_rotations: np.ndarray, joint_positions: np.ndarray, fps: float) -> np.ndarray:
    """:func:`motion_features` of (T >= 2) frames' global rotations (T, 22, 3, 3) and joint
    positions (T, 22, 3)."""
    frames = len(global_rotations)
    yaw = yaw_of(global_rotations[:, 0])
    h_t = np.swapaxes(
        rotation_about_y(yaw), -1, -2
    )  # world -> body frame (rotation only; frame.body_heading)
    joints = list(FEATURE_JOINTS)
    r = matrix_to_axis_angle(h_t[:, None] @ global_rotations[:, joints]).reshape(frames, -1)
    vel = _first_difference(joint_positions[:, joints], fps)
    v = np.einsum("tij,tkj->tki", h_t, vel).reshape(frames, -1)
    t = np.einsum("tij,tj->ti", h_t, _first_difference(joint_positions[:, 0], fps))
    dyaw = np.empty_like(yaw)
    dyaw[1:] = np.angle(np.exp(1j * (yaw[1:] - yaw[:-1])))
    dyaw[0] = dyaw[1] if len(yaw) > 1 else 0.0
    w = (dyaw * fps)[:, None]
    return np.concatenate([r, v, t, w], axis=1).astype(np.float32)


def causal_features(motion: Motion) -> np.ndarray:
    """Features as a stream sees them: frame t from frames t-1 and t only (frame 0: zero
    velocities). Equal to :func:`motion_features` from frame 1 on. In C where compiled (the same
    formulas; a stream computes them per frame), else numpy."""
    lib = native.load_kernel()
    if lib is not None:
        return native.causal_features(
            lib, motion.global_rotations, motion.joint_positions, joints=FEATURE_JOINTS, fps=motion.fps
        )
    if motion.num_frames == 1:
        return motion_features(Motion.concatenate([motion, motion]))[-1:]
    feats = motion_features(motion)
    feats[0] = motion_features(Motion.concatenate([motion.slice(0, 1)] * 2))[-1]
    return feats


def pair_features_batch(previous: list[tuple[np.ndarray, np.ndarray] | None], current: Motion) -> np.ndarray:
    """Features (N, 124) of each frame i of ``current`` given the pose before it, ``previous[i]``:
    its global rotations (22, 3, 3) and joint positions (22, 3), or None at a start (the frame
    repeated: zero velocities). The frames are independent (N characters' poses in one call);
    row i equals the last row of :func:`causal_features` of that character's two frames."""
    g_rot, g_pos = current.global_rotations, current.joint_positions
    n = current.num_frames
    if len(previous) != n:
        raise ValueError(f"{n} poses but {len(previous)} previous poses")
    # pose i and the one before it as frames 2i and 2i + 1 of one sequence: a causal feature frame
    # depends on its own frame and the one before only, so the odd frames are the pairs' features
    rot, pos = np.empty((2 * n, *g_rot.shape[1:])), np.empty((2 * n, *g_pos.shape[1:]))
    rot[1::2], pos[1::2] = g_rot, g_pos
    for i, prev in enumerate(previous):
        rot[2 * i], pos[2 * i] = (g_rot[i], g_pos[i]) if prev is None else prev
    lib = native.load_kernel()
    if lib is not None:
        return native.causal_features(lib, rot, pos, joints=FEATURE_JOINTS, fps=current.fps)[1::2]
    return _features(rot, pos, current.fps)[1::2]


@dataclass
class FeatureStats:
    """Standardisation statistics; stored with a trained model."""

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, features: list[np.ndarray] | np.ndarray, min_std: float = 1e-3) -> "FeatureStats":
        stacked = (
            np.concatenate(features, axis=0)
            if isinstance(features, list)
            else features.reshape(-1, features.shape[-1])
        )
        mean = stacked.mean(0, dtype=np.float64)
        std = np.maximum(stacked.std(0, dtype=np.float64), min_std)
        return cls(mean.astype(np.float32), std.astype(np.float32))

    def normalize(self, features: np.ndarray) -> np.ndarray:
        return ((features - self.mean) / self.std).astype(np.float32)

    def denormalize(self, features: np.ndarray) -> np.ndarray:
        return (features * self.std + self.mean).astype(np.float32)

    def to_dict(self) -> dict[str, np.ndarray]:
        return {"mean": self.mean, "std": self.std}

    @classmethod
    def from_dict(cls, d: dict[str, np.ndarray]) -> "FeatureStats":
        mean, std = np.asarray(d["mean"], np.float32), np.asarray(d["std"], np.float32)
        if mean.shape != std.shape or mean.ndim != 1:
            raise ValueError(f"feature statistics have shapes {mean.shape} and {std.shape}")
        return cls(mean, std)
