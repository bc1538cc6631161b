"""Where each ankle goes, frame by frame, for a `Plan`: planted at mid-stance beside the root path
for each of its stances (sole on the ground), and between them on a swing relative to the moving
root (a cubic Hermite curve that leaves and lands with zero world velocity, lifted by a bump; the
foot's yaw turning on a quintic, zero velocity and acceleration at lift-off and touch-down); then
the two feet kept apart (:func:`keep_feet_apart`). :mod:`.engine` reaches the targets by leg IK."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from ..rotations import rotation_about_y
from .plan import FootPlan, Plan, bump, quintic

ANKLE_HEIGHT = 0.08  # ankle joint above the sole with the foot flat (canonical skeleton)


def foot_targets(
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


def keep_feet_apart(plan: Plan, foot_data: dict) -> dict:
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
