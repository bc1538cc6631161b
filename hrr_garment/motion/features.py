"""Per-frame motion features (paper 3.3; DESIGN 4) and sliding windows.

f_t = [r (60); v (60); t (3); w (1)] = 124 values, all in the heading frame at frame t (origin at
the pelvis projected on the ground, rotated by the pelvis yaw only):

* r: global rotation of each of the 20 feature joints, expressed in the heading frame, axis-angle;
* v: world velocity of each feature joint, (p_t - p_{t-1}) / dt, rotated into the heading frame;
* t: root (pelvis) translation velocity in the heading frame;
* w: yaw angular velocity (rad/s), wrapped to (-pi, pi] per frame step.

Velocities at frame 0 use the first difference (frames 0 and 1), so every frame has a value. The
features do not change when the whole motion is translated or rotated about the vertical axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MotionError
from .motion import Motion
from .rotations import matrix_to_axis_angle, rotation_about_y, yaw_of
from .skeleton import FEATURE_JOINTS

FEATURE_DIM = 124
DEFAULT_WINDOW = 10
# Column slices of the feature vector.
SLICE_R = slice(0, 60)
SLICE_V = slice(60, 120)
SLICE_T = slice(120, 123)
SLICE_W = slice(123, 124)


def heading(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: yaw angle (T,) and heading rotation (T, 3, 3) of the pelvis."""
    yaw = yaw_of(motion.global_rotations[:, 0])
    return yaw, rotation_about_y(yaw)


def _first_difference(x: np.ndarray, fps: float) -> np.ndarray:
    d = np.empty_like(x)
    d[1:] = (x[1:] - x[:-1]) * fps
    d[0] = d[1] if len(x) > 1 else 0.0
    return d


def motion_features(motion: Motion) -> np.ndarray:
    """(T, 124) float32 features of a canonical motion."""
    if motion.num_frames < 2:
        raise MotionError(motion.source or "motion", f"needs at least 2 frames for velocities, has {motion.num_frames}")
    yaw, h = heading(motion)
    h_t = np.swapaxes(h, -1, -2)  # world -> heading frame
    joints = list(FEATURE_JOINTS)
    g_rot = motion.global_rotations[:, joints]
    r = matrix_to_axis_angle(h_t[:, None] @ g_rot).reshape(motion.num_frames, -1)
    vel = _first_difference(motion.joint_positions[:, joints], motion.fps)
    v = np.einsum("tij,tkj->tki", h_t, vel).reshape(motion.num_frames, -1)
    t = np.einsum("tij,tj->ti", h_t, _first_difference(motion.joint_positions[:, 0], motion.fps))
    dyaw = np.empty_like(yaw)
    dyaw[1:] = np.angle(np.exp(1j * (yaw[1:] - yaw[:-1])))
    dyaw[0] = dyaw[1] if len(yaw) > 1 else 0.0
    w = (dyaw * motion.fps)[:, None]
    return np.concatenate([r, v, t, w], axis=1).astype(np.float32)


def windows(features: np.ndarray, size: int = DEFAULT_WINDOW, stride: int = 1, source: str = "motion") -> np.ndarray:
    """(N, size, D) overlapping windows, N = (T - size) // stride + 1 (a view, no copy)."""
    if features.shape[0] < size:
        raise MotionError(source, f"clip has {features.shape[0]} frames, shorter than one window of {size} frames")
    view = np.lib.stride_tricks.sliding_window_view(features, size, axis=0)  # (N, D, size)
    return np.swapaxes(view, 1, 2)[::stride]


@dataclass
class FeatureStats:
    """Standardisation statistics; stored with a trained model."""

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, features: list[np.ndarray] | np.ndarray, min_std: float = 1e-3) -> "FeatureStats":
        stacked = np.concatenate(features, axis=0) if isinstance(features, list) else features.reshape(-1, features.shape[-1])
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
