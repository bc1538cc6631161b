"""Turns a `Plan` (root path, footsteps, upper-body curves) into a canonical `Motion`.

Feet are placed by footstep planning (:mod:`.foot_targets`) and analytic two-bone leg IK, so a
planted foot stays exactly where it landed (no skating) with its sole on the ground (no sinking);
the pelvis is lowered smoothly wherever a leg could not otherwise reach its foot.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from ..motion import FPS, Motion
from ..rotations import (
    axis_angle_to_matrix,
    matrix_to_axis_angle,
    normalize,
    rotation_about_y,
)
from ..skeleton import JOINT_INDEX as J
from ..skeleton import PARENTS, REST_OFFSETS, global_to_local
from .foot_targets import ANKLE_HEIGHT, foot_targets, keep_feet_apart
from .plan import Plan

THIGH = float(np.linalg.norm(REST_OFFSETS[J["l_knee"]]))
SHIN = float(np.linalg.norm(REST_OFFSETS[J["l_ankle"]]))
REACH = 0.995 * (THIGH + SHIN)
MAX_DROP = 0.05


def rot_x(a: np.ndarray) -> np.ndarray:
    """Rotations about X by angles (N,) -> (N, 3, 3)."""
    return axis_angle_to_matrix(np.stack([a, 0 * a, 0 * a], -1))


def rot_z(a: np.ndarray) -> np.ndarray:
    """Rotations about Z by angles (N,) -> (N, 3, 3)."""
    return axis_angle_to_matrix(np.stack([0 * a, 0 * a, a], -1))


def _two_bone_ik(
    hip: np.ndarray, ankle: np.ndarray, pole: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thigh and shin global rotations (N,3,3) and the reached ankle, knee bending towards ``pole``."""
    d = ankle - hip
    dist = np.linalg.norm(d, axis=1, keepdims=True)
    d = d / np.maximum(dist, 1e-9)
    dist = np.clip(dist, abs(THIGH - SHIN) + 1e-4, REACH)
    along = (THIGH**2 - SHIN**2 + dist**2) / (2 * dist)
    h = np.sqrt(np.maximum(THIGH**2 - along**2, 0.0))
    bend = normalize(pole - (pole * d).sum(1, keepdims=True) * d)
    knee = hip + along * d + h * bend
    reached = hip + dist * d
    hinge = normalize(np.cross(d, -bend))
    rest_shin = normalize(REST_OFFSETS[J["l_ankle"]].astype(np.float64))
    thigh = (
        _bone_frame(normalize(knee - hip), hinge)
        @ _bone_frame(np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0])).T
    )
    shin = _bone_frame(normalize(reached - knee), hinge) @ _bone_frame(rest_shin, np.array([1.0, 0.0, 0.0])).T
    return thigh, shin, reached


def _bone_frame(direction: np.ndarray, hinge: np.ndarray) -> np.ndarray:
    e1 = normalize(direction)
    e2 = normalize(hinge - (hinge * e1).sum(-1, keepdims=True) * e1)
    return np.stack([e1, e2, np.cross(e1, e2)], -1)


def build_motion(plan: Plan, source: str) -> Motion:
    """A Plan as canonical motion: root path, pelvis, spine, arms and IK legs."""
    n = len(plan.t)
    heading = rotation_about_y(plan.yaw)
    pelvis_rot = heading @ rot_x(plan.curve(plan.pelvis_pitch)) @ rot_z(plan.curve(plan.pelvis_roll))
    pelvis_y = plan.pelvis_y.copy()
    takeoff_y = plan.takeoff_height if plan.takeoff_height is not None else float(np.max(plan.pelvis_y))
    hip_off = {s: REST_OFFSETS[J[f"{s}_hip"]].astype(np.float64) for s in "lr"}
    foot_data = keep_feet_apart(
        plan, {f.side: foot_targets(plan, f, plan.pelvis_y, takeoff_y=takeoff_y) for f in plan.feet}
    )
    # Lower the pelvis where a leg cannot reach its target; dilate then smooth the correction so the
    # result stays continuous in velocity and still lowers at least as much as needed.
    for _ in range(6):
        drop = np.zeros(n)
        for side, (target, _, _) in foot_data.items():
            hip = np.stack([plan.root_xz[:, 0], pelvis_y, plan.root_xz[:, 1]], 1) + pelvis_rot @ hip_off[side]
            horiz = np.linalg.norm((target - hip)[:, [0, 2]], axis=1)
            max_hip_y = target[:, 1] + np.sqrt(np.maximum(REACH**2 - horiz**2, 0.0))
            drop = np.maximum(drop, hip[:, 1] - max_hip_y)
        if drop.max() <= 1e-5:
            break
        # At most MAX_DROP per pass: a target out of reach horizontally is left to the IK clamp.
        drop = gaussian_filter1d(
            maximum_filter1d(np.clip(drop, 0, MAX_DROP) * 1.05 + 1e-4 * (drop > 0), size=9), 2.0
        )
        pelvis_y = pelvis_y - drop
        foot_data = keep_feet_apart(
            plan, {f.side: foot_targets(plan, f, pelvis_y, takeoff_y=takeoff_y) for f in plan.feet}
        )
    glob = np.zeros((n, len(PARENTS), 3, 3))
    glob[:] = np.eye(3)
    glob[:, J["pelvis"]] = pelvis_rot
    root = np.stack([plan.root_xz[:, 0], pelvis_y, plan.root_xz[:, 1]], 1)
    for side, (target, foot_yaw, _) in foot_data.items():
        hip = root + pelvis_rot @ hip_off[side]
        # Knees point between the foot and the pelvis heading, slightly outwards: following the
        # planted foot alone swung a knee into the other leg while the pelvis turned over it.
        sign = 1.0 if side == "l" else -1.0
        pole = rotation_about_y(foot_yaw) @ np.array([0.0, 0.0, 1.0]) + rotation_about_y(plan.yaw) @ np.array(
            [0.25 * sign, 0.0, 1.0]
        )
        thigh, shin, _ = _two_bone_ik(hip, target, pole)
        glob[:, J[f"{side}_hip"]] = thigh
        glob[:, J[f"{side}_knee"]] = shin
        swing = ~foot_data[side][2]
        toe_up = np.where(
            swing, 0.25 * np.clip((target[:, 1] - ANKLE_HEIGHT - plan.ground_y) / 0.1, 0, 1), 0.0
        )
        glob[:, J[f"{side}_ankle"]] = rotation_about_y(foot_yaw) @ rot_x(-toe_up)
        glob[:, J[f"{side}_foot"]] = glob[:, J[f"{side}_ankle"]]
    # Spine: spread the twist and lean over three joints; head keeps looking along the heading.
    twist, lean = plan.curve(plan.spine_twist), plan.curve(plan.spine_lean)
    step = rotation_about_y(twist / 3.0) @ rot_x(lean / 3.0) @ rot_z(-plan.curve(plan.pelvis_roll) / 3.0)
    for joint in ("spine1", "spine2", "spine3"):
        glob[:, J[joint]] = glob[:, PARENTS[J[joint]]] @ step
    chest = glob[:, J["spine3"]]
    head_rot = (
        heading
        @ rotation_about_y(plan.curve(plan.head_yaw))
        @ rot_x(0.5 * plan.curve(plan.pelvis_pitch) + 0.05)
    )
    glob[:, J["neck"]] = _halfway(chest, head_rot)
    glob[:, J["head"]] = head_rot
    for side, sign in (("l", 1.0), ("r", -1.0)):
        # the collar as the performer carries it (posture.py)
        glob[:, J[f"{side}_collar"]] = chest @ axis_angle_to_matrix(
            plan.collar_rotation.get(side, np.zeros(3))
        )
        hang = rot_z(-sign * (np.pi / 2 - 0.16 - plan.arm_abduction.get(side, np.zeros(n))))
        upper = chest @ rot_x(-plan.arm_swing.get(side, np.zeros(n))) @ hang
        hinge_rest = np.array([0.0, -1.0, 0.0]) if side == "l" else np.array([0.0, 1.0, 0.0])
        hinge = upper @ hinge_rest
        flex = plan.elbow_flex.get(side, np.full(n, 0.2))
        glob[:, J[f"{side}_shoulder"]] = upper
        glob[:, J[f"{side}_elbow"]] = axis_angle_to_matrix(hinge * flex[:, None]) @ upper
        glob[:, J[f"{side}_wrist"]] = glob[:, J[f"{side}_elbow"]]
    local = global_to_local(glob, PARENTS)
    crop = slice(plan.pad, n - plan.pad)
    return Motion(local[crop], root[crop], FPS, source=source)


def _halfway(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation halfway between a and b (per frame)."""
    rel = matrix_to_axis_angle(np.swapaxes(a, -1, -2) @ b)
    return a @ axis_angle_to_matrix(0.5 * rel)
