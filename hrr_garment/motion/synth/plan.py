"""What a procedural clip is made from: a :class:`Plan` (root path, footsteps, upper-body curves)
and its :class:`FootPlan` per foot, with the smooth curves the kinds shape them with.
:mod:`.engine` turns a plan into motion; :mod:`.kinds` makes plans."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def quintic(s: np.ndarray) -> np.ndarray:
    """Smoothstep with zero first and second derivatives at 0 and 1."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def bump(s: np.ndarray) -> np.ndarray:
    """0 at the ends, 1 in the middle, zero slope at the ends."""
    s = np.clip(s, 0.0, 1.0)
    return 16.0 * s * s * (1.0 - s) * (1.0 - s)


@dataclass
class FootPlan:
    """Footsteps of one foot: stance intervals in seconds (sorted, disjoint)."""

    side: str  # "l" or "r"
    stances: list[tuple[float, float]]
    lateral: float = 0.1  # plant offset from the root path, metres (outwards)
    forward: float = 0.0  # plant offset along the heading
    lift: float = 0.08  # swing height of the ankle, metres
    follow_pelvis: bool = False  # in swing, also rise with the pelvis above its take-off height (jumps)
    pivot: bool = False  # a planted foot turns with the body (spins) instead of keeping its yaw
    free_target: np.ndarray | None = (
        None  # (N, 3) ankle offset in the heading frame for a foot that never lands
    )


@dataclass
class Plan:
    """Everything a procedural clip needs, sampled on a padded 30 fps grid ``t`` (seconds)."""

    t: np.ndarray
    root_xz: np.ndarray  # (N, 2) pelvis ground position (x, z)
    yaw: np.ndarray  # (N,) heading of the pelvis
    pelvis_y: np.ndarray  # (N,) desired pelvis height (lowered where legs cannot reach)
    feet: list[FootPlan]
    pelvis_pitch: np.ndarray | None = None  # forward lean of the pelvis (rad)
    pelvis_roll: np.ndarray | None = None  # sideways tilt (rad, +: left hip up)
    spine_twist: np.ndarray | None = None  # yaw of the chest relative to the pelvis (rad)
    spine_lean: np.ndarray | None = None  # extra forward lean of the chest (rad)
    head_yaw: np.ndarray | None = None  # look direction relative to the heading (rad)
    arm_swing: dict[str, np.ndarray] = field(default_factory=dict)  # side -> forward swing (rad)
    arm_abduction: dict[str, np.ndarray] = field(default_factory=dict)  # side -> angle from hanging (rad)
    elbow_flex: dict[str, np.ndarray] = field(default_factory=dict)  # side -> flexion (rad)
    # side -> (3,) rotation vector of the collar from the chest
    collar_rotation: dict[str, np.ndarray] = field(default_factory=dict)
    pad: int = 0  # frames of padding at each end, cropped from the output
    ground_y: float = 0.0
    takeoff_height: float | None = None  # pelvis height at take-off, for feet that follow the pelvis

    def curve(self, value: np.ndarray | None) -> np.ndarray:
        return np.zeros_like(self.t) if value is None else value
