"""Turns a `Plan` (root path, footsteps, upper-body curves) into a canonical `Motion`.

Feet are placed by footstep planning and analytic two-bone leg IK, so a planted foot stays exactly
where it landed (no skating) with its sole on the ground (no sinking); the pelvis is lowered
smoothly wherever a leg could not otherwise reach its foot. Swing feet travel on quintic curves
(zero velocity and acceleration at lift-off and touch-down).
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
from .plan import FootPlan, Plan, bump, quintic

ANKLE_HEIGHT = 0.08  # ankle joint above the sole with the foot flat (canonical skeleton)
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


def _foot_targets(
    plan: Plan, foot: FootPlan, pelvis_y: np.ndarray, takeoff_y: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame: ankle target (N,3), foot yaw (N,), stance mask (N,)."""
    t, n = plan.t, len(plan.t)
    sign = 1.0 if foot.side == "l" else -1.0
    heading = rotation_about_y(plan.yaw)
    if not foot.stances:
        offset = (
            foot.free_target
            if foot.free_target is not None
            else np.tile([sign * foot.lateral, ANKLE_HEIGHT + foot.lift, -0.2], (n, 1))
        )
        pos = np.concatenate([plan.root_xz[:, :1], np.zeros((n, 1)), plan.root_xz[:, 1:]], 1)
        target = pos + np.einsum("nij,nj->ni", heading, offset * np.array([1.0, 0.0, 1.0]))
        target[:, 1] = plan.ground_y + offset[:, 1]
        return target, plan.yaw.copy(), np.zeros(n, bool)
    plants, plant_yaw = [], []
    for a, b in foot.stances:
        m = int(np.clip(np.searchsorted(t, 0.5 * (a + b)), 0, n - 1))
        local = heading[m] @ np.array([sign * foot.lateral, 0.0, foot.forward])
        plants.append(
            np.array(
                [plan.root_xz[m, 0] + local[0], plan.ground_y + ANKLE_HEIGHT, plan.root_xz[m, 1] + local[2]]
            )
        )
        plant_yaw.append(plan.yaw[m])
    target = np.zeros((n, 3))
    yaw = np.zeros(n)
    stance = np.zeros(n, bool)
    starts = np.array([s[0] for s in foot.stances])
    root_vel = np.gradient(plan.root_xz, t, axis=0)
    swing_ends: dict[int, tuple[np.ndarray, ...]] = {}
    for i in range(n):
        k = int(np.searchsorted(starts, t[i], side="right")) - 1  # last stance starting at or before t
        if k >= 0 and t[i] <= foot.stances[k][1]:
            target[i], stance[i] = plants[k], True
            yaw[i] = plan.yaw[i] if foot.pivot else plant_yaw[k]
            continue
        if k < 0:  # before the first stance: hold the first plant (padding region)
            target[i], yaw[i], stance[i] = plants[0], plant_yaw[0], True
            continue
        if k + 1 >= len(plants):  # after the last stance
            target[i], yaw[i], stance[i] = plants[k], plant_yaw[k], True
            continue
        t0, t1 = foot.stances[k][1], foot.stances[k + 1][0]
        s = (t[i] - t0) / (t1 - t0)
        q = quintic(s)
        # Swing relative to the moving root (cubic Hermite), so the foot stays within reach of the
        # hip and leaves and lands with zero world velocity.
        if k not in swing_ends:  # root position and velocity at lift-off and touch-down, once per swing
            r0, r1, v0, v1 = (
                np.array([np.interp(x, t, arr[:, c]) for c in (0, 1)])
                for arr, x in ((plan.root_xz, t0), (plan.root_xz, t1), (root_vel, t0), (root_vel, t1))
            )
            swing_ends[k] = (plants[k][[0, 2]] - r0, plants[k + 1][[0, 2]] - r1, v0, v1)
        rel0, rel1, v0, v1 = swing_ends[k]
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        rel = h00 * rel0 - h10 * (t1 - t0) * v0 + h01 * rel1 - h11 * (t1 - t0) * v1
        target[i] = [plan.root_xz[i, 0] + rel[0], plants[k][1], plan.root_xz[i, 1] + rel[1]]
        if foot.pivot:
            yaw[i] = plan.yaw[i]
        else:
            yaw[i] = plant_yaw[k] + q * np.angle(np.exp(1j * (plant_yaw[k + 1] - plant_yaw[k])))
        rise = foot.lift * bump(s)
        if foot.follow_pelvis:
            rise += max(0.0, pelvis_y[i] - takeoff_y)
        target[i, 1] += rise
    return target, yaw, stance


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


MIN_FOOT_GAP = 0.15  # ankle centres, horizontally: shins (r 5.2 cm) stay 4.6 cm apart


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges where ``mask`` is True."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return list(zip(edges[::2], edges[1::2]))


def _lateral_deficit(own: np.ndarray, other: np.ndarray, lateral: np.ndarray, sign: float) -> np.ndarray:
    """How far ``own`` must move outwards (along ``sign * lateral``) to be MIN_FOOT_GAP from ``other``
    horizontally; feet far apart front-to-back need no sideways gap (a runner's feet land in line)."""
    d = (own - other) * np.array([1.0, 0.0, 1.0])
    side = sign * (d * lateral).sum(-1)
    along = np.linalg.norm(d - (d * lateral).sum(-1, keepdims=True) * lateral, axis=-1)
    need = np.sqrt(np.maximum(MIN_FOOT_GAP**2 - along**2, 0.0))
    return np.where(along < MIN_FOOT_GAP, np.maximum(need - side, 0.0), 0.0)


def _keep_feet_apart(plan: Plan, foot_data: dict) -> dict:
    """Keep each foot out of the other leg: at least MIN_FOOT_GAP between ankles, left on the left.

    Turning, side-stepping and curving gaits otherwise plant or swing one foot into the other leg.
    A stance that lands too close to the other foot's neighbouring stances is moved outwards as a
    whole (it stays planted), the move eased in over the swing before it and out over the swing
    after. A swinging foot that passes too close is pushed outwards, weighted by a bump over the
    swing so that lift-off and touch-down are untouched.
    """
    if set(foot_data) != {"l", "r"}:
        return foot_data
    lateral = rotation_about_y(plan.yaw) @ np.array([1.0, 0.0, 0.0])  # (N, 3): towards the left
    targets = {k: v[0].copy() for k, v in foot_data.items()}
    stance = {k: v[2] for k, v in foot_data.items()}
    n = len(plan.t)
    for side, other, sign in (("l", "r", 1.0), ("r", "l", -1.0)):
        runs, other_runs = _runs(stance[side]), _runs(stance[other])
        for k, (a, b) in enumerate(runs):
            if a == 0:
                continue  # the first stance is where the clip starts; leave it
            near = (
                [r for r in other_runs if r[0] < b + 2 and r[1] > a - 2]
                or [min(other_runs, key=lambda r: min(abs(r[0] - b), abs(r[1] - a)))]
                if other_runs
                else []
            )
            mid = (a + b) // 2
            deficit = max(
                (
                    float(
                        _lateral_deficit(
                            targets[side][mid], targets[other][(r[0] + r[1]) // 2], lateral[mid], sign
                        )
                    )
                    for r in near
                ),
                default=0.0,
            )
            before = runs[k - 1][1] if k > 0 else a
            after = runs[k + 1][0] if k + 1 < len(runs) else b
            if deficit <= 0 or a - before < 4 or (after - b < 4 and k + 1 < len(runs)):
                continue  # (no swing long enough to ease the move in or out: leave the stance)
            ramp = np.zeros(n)
            ramp[a:b] = 1.0
            ramp[before:a] = quintic(np.linspace(0, 1, a - before + 2)[1:-1])
            ramp[b:after] = quintic(np.linspace(1, 0, after - b + 2)[1:-1])
            targets[side] += ramp[:, None] * (sign * deficit * lateral[mid] * np.array([1.0, 0.0, 1.0]))
    for side, other, sign in (("l", "r", 1.0), ("r", "l", -1.0)):
        weight = np.zeros(n)
        for a, b in _runs(~stance[side]):
            weight[a:b] = bump(np.linspace(0, 1, b - a + 2)[1:-1]) ** 2  # flatter than the lift at the ends
        # Smoothed (then widened by a max filter so the smoothing does not undercut the need) to
        # keep accelerations bounded where the deficit changes quickly.
        deficit = _lateral_deficit(targets[side], targets[other], lateral, sign)
        push = weight * gaussian_filter1d(maximum_filter1d(deficit, size=5), 2.0)
        targets[side] += sign * push[:, None] * lateral * np.array([1.0, 0.0, 1.0])
    return {k: (targets[k], v[1], v[2]) for k, v in foot_data.items()}


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
    foot_data = _keep_feet_apart(
        plan, {f.side: _foot_targets(plan, f, plan.pelvis_y, takeoff_y) for f in plan.feet}
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
        foot_data = _keep_feet_apart(
            plan, {f.side: _foot_targets(plan, f, pelvis_y, takeoff_y) for f in plan.feet}
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
        glob[:, J[f"{side}_collar"]] = chest
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
