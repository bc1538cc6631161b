"""The canonical skeleton: 22 SMPL-order body joints with the project's own rest offsets.

Y is up, metres, T-pose, the character faces +Z and its left side is +X (SMPL's convention).
The rest offsets are the project's own (SMPL model files are not redistributable); they describe
an adult about 1.70 m tall with the ankles 8 cm above the ground and the sole at y = 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .rotations import Array, _stack

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "l_hip", "r_hip", "spine1", "l_knee", "r_knee", "spine2", "l_ankle", "r_ankle",
    "spine3", "l_foot", "r_foot", "neck", "l_collar", "r_collar", "head", "l_shoulder",
    "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
)  # fmt: skip
NUM_JOINTS = len(JOINT_NAMES)
JOINT_INDEX = {name: i for i, name in enumerate(JOINT_NAMES)}

PARENTS: tuple[int, ...] = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)
# Each joint's left-right counterpart (centre joints are their own).
MIRROR_JOINTS: tuple[int, ...] = tuple(
    JOINT_INDEX[{"l": "r", "r": "l"}[n[0]] + n[1:]] if n[:2] in ("l_", "r_") else i
    for i, n in enumerate(JOINT_NAMES)
)

# The 20 joints used by motion features: all but the two toe joints (paper 3.3).
FEATURE_JOINTS: tuple[int, ...] = tuple(i for i, n in enumerate(JOINT_NAMES) if n not in ("l_foot", "r_foot"))

# Parent-relative rest offsets in metres (right side mirrors the left in x).
_LEFT_OFFSETS = {
    "l_hip": (0.09, -0.08, 0.0),
    "l_knee": (0.0, -0.40, 0.0),
    "l_ankle": (0.0, -0.40, -0.02),
    "l_foot": (0.0, -0.055, 0.13),
    "l_collar": (0.075, 0.12, -0.01),
    "l_shoulder": (0.11, 0.03, -0.01),
    "l_elbow": (0.26, 0.0, 0.0),
    "l_wrist": (0.25, 0.0, 0.0),
}
_CENTRE_OFFSETS = {
    "pelvis": (0.0, 0.0, 0.0),
    "spine1": (0.0, 0.11, -0.01),
    "spine2": (0.0, 0.13, 0.0),
    "spine3": (0.0, 0.06, 0.02),
    "neck": (0.0, 0.21, -0.02),
    "head": (0.0, 0.09, 0.04),
}


def _canonical_offsets() -> np.ndarray:
    table = dict(_CENTRE_OFFSETS)
    for name, (x, y, z) in _LEFT_OFFSETS.items():
        table[name] = (x, y, z)
        table["r" + name[1:]] = (-x, y, z)
    return np.array([table[n] for n in JOINT_NAMES], dtype=np.float32)


REST_OFFSETS = _canonical_offsets()
# Pelvis height in the rest pose that puts the sole on the ground.
REST_PELVIS_HEIGHT = 0.96
# Top of the head above the head joint (the skeleton has no head-top joint).
HEAD_TOP_ABOVE_HEAD_JOINT = 0.14

# Points on each foot's sole, in the local frame of the joint they hang from: heel under the ankle,
# ball and toe tip under the toe joint. Used for ground contact by the procedural motions and by
# ground alignment / foot metrics, so both agree on what "on the ground" means.
SOLE_POINTS: tuple[tuple[str, tuple[float, float, float]], ...] = (
    ("l_ankle", (0.0, -0.08, -0.04)),
    ("l_foot", (0.0, -0.025, 0.0)),
    ("l_foot", (0.0, -0.025, 0.05)),
    ("r_ankle", (0.0, -0.08, -0.04)),
    ("r_foot", (0.0, -0.025, 0.0)),
    ("r_foot", (0.0, -0.025, 0.05)),
)


def rest_positions(offsets: np.ndarray, parents: tuple[int, ...] | list[int]) -> np.ndarray:
    """(J, 3) rest-pose joint positions of any tree: offsets accumulated from the root (float64)."""
    pos = np.zeros((len(parents), 3), dtype=np.float64)
    for j, p in enumerate(parents):
        pos[j] = offsets[j] if p < 0 else pos[p] + offsets[j]
    return pos


@dataclass(frozen=True)
class Skeleton:
    """A kinematic tree: parent indices and parent-relative rest offsets (T-pose, metres)."""

    names: tuple[str, ...] = JOINT_NAMES
    parents: tuple[int, ...] = PARENTS
    offsets: np.ndarray = field(default_factory=lambda: REST_OFFSETS.copy())

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def rest_positions(self, root: np.ndarray | None = None) -> np.ndarray:
        """(J, 3) joint positions in the rest pose with the root at ``root`` (default origin)."""
        pos = rest_positions(self.offsets, self.parents)
        if root is not None:
            pos += np.asarray(root) - pos[0]
        return pos

    def bone_length(self, joint: str) -> float:
        return float(np.linalg.norm(self.offsets[self.names.index(joint)]))


CANONICAL = Skeleton()


def forward_kinematics(
    local_rot: Array, root_pos: Array, offsets: Array, parents: tuple[int, ...]
) -> tuple[Array, Array]:
    """Batched FK. local_rot (..., J, 3, 3), root_pos (..., 3), offsets (J, 3) or per frame (..., J, 3).

    Returns (global rotations (..., J, 3, 3), global positions (..., J, 3)). Works for numpy and
    torch; a root's offset is ignored (its position is ``root_pos``).
    """
    g_rot: list = [None] * len(parents)
    g_pos: list = [None] * len(parents)
    for j, p in enumerate(parents):
        if p < 0:
            g_rot[j] = local_rot[..., j, :, :]
            g_pos[j] = root_pos
        else:
            g_rot[j] = g_rot[p] @ local_rot[..., j, :, :]
            g_pos[j] = g_pos[p] + (g_rot[p] @ offsets[..., j, :, None])[..., 0]
    return _stack(g_rot, -3), _stack(g_pos, -2)


def global_to_local(global_rot: np.ndarray, parents: tuple[int, ...]) -> np.ndarray:
    """Inverse of the rotation part of FK: local_j = global_parent^T @ global_j."""
    local = np.empty_like(global_rot)
    for j, p in enumerate(parents):
        local[..., j, :, :] = (
            global_rot[..., j, :, :]
            if p < 0
            else np.swapaxes(global_rot[..., p, :, :], -1, -2) @ global_rot[..., j, :, :]
        )
    return local


def sole_points(global_rot: np.ndarray, global_pos: np.ndarray) -> np.ndarray:
    """(..., 6, 3) world positions of the sole points of both feet (see SOLE_POINTS)."""
    cols = []
    for joint, offset in SOLE_POINTS:
        j = JOINT_INDEX[joint]
        cols.append(
            global_pos[..., j, :] + global_rot[..., j, :, :] @ np.asarray(offset, dtype=global_rot.dtype)
        )
    return np.stack(cols, -2)


def sole_heights(global_rot: np.ndarray, global_pos: np.ndarray) -> np.ndarray:
    """(..., 6) heights above y=0 of the sole points of both feet."""
    return sole_points(global_rot, global_pos)[..., 1]
