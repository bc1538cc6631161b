"""Stepping: the :class:`Gait` numbers of a stepping kind and the plan they make (alternating feet
on stance intervals, arm swing opposite the legs, pelvis bob), and the walking cadence."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .basics import STAND, ground_path
from .plan import FootPlan, Plan


def stance_intervals(t: np.ndarray, period: float, duty: float, phase: float) -> list[tuple[float, float]]:
    """Stance intervals centred at phase + k * period covering the grid."""
    half = 0.5 * duty * period
    ks = np.arange(np.floor((t[0] - phase) / period) - 1, np.ceil((t[-1] - phase) / period) + 2)
    return [(phase + k * period - half, phase + k * period + half) for k in ks]


@dataclass(frozen=True)
class Gait:
    """A stepping kind's numbers for :func:`gait_plan` (metres, seconds, radians)."""

    speed: float | np.ndarray  # forward speed along the heading (m/s; negative: backwards)
    side_speed: float | np.ndarray  # sideways speed (m/s; positive: to the character's left)
    period: float  # seconds per stride (two steps)
    duty: float  # fraction of the stride each foot is planted
    lift: float  # swing foot height
    lateral: float  # half the stance width
    bob: float  # pelvis bob amplitude
    swing: float  # arm swing amplitude
    flex: float  # mean elbow flexion
    lean: float = 0.0  # forward lean of the pelvis (the spine takes half)
    pivot: bool = False  # planted feet turn with the body (spins)


def gait_plan(rng, t, pad, *, yaw, gait: Gait) -> Plan:
    """Shared by every stepping kind: alternating feet, arm swing opposite the legs."""
    period = gait.period
    phase = rng.uniform(0, period)
    w = 2 * np.pi * (t - phase) / period
    feet = [
        FootPlan(
            "l",
            stance_intervals(t, period, gait.duty, phase),
            lateral=gait.lateral,
            lift=gait.lift,
            pivot=gait.pivot,
        ),
        FootPlan(
            "r",
            stance_intervals(t, period, gait.duty, phase + 0.5 * period),
            lateral=gait.lateral,
            lift=gait.lift,
            pivot=gait.pivot,
        ),
    ]
    bob, swing, flex, lean = gait.bob, gait.swing, gait.flex, gait.lean
    return Plan(
        t=t,
        root_xz=ground_path(t, yaw, gait.speed, sideways=gait.side_speed),
        yaw=yaw,
        pelvis_y=STAND - 2 * bob + bob * np.cos(2 * w),
        feet=feet,
        pelvis_pitch=np.full_like(t, lean),
        pelvis_roll=0.05 * np.sin(w),
        spine_twist=-0.08 * np.sin(w) * min(1.0, abs(float(np.mean(gait.speed))) + 0.2),
        spine_lean=np.full_like(t, 0.5 * lean),
        arm_swing={"l": -swing * np.sin(w), "r": swing * np.sin(w)},
        arm_abduction={"l": np.full_like(t, 0.02), "r": np.full_like(t, 0.02)},
        elbow_flex={"l": flex + 0.3 * flex * np.sin(w), "r": flex - 0.3 * flex * np.sin(w)},
        pad=pad,
    )


def walking_cadence(speed: float) -> float:
    """Steps per second for walking at ``speed`` m/s (step length at most 0.65 m: the feet stay flat
    in stance, so longer steps would need a deep crouch to keep both feet within reach)."""
    return max(1.4 + 0.45 * (abs(speed) - 0.6), abs(speed) / 0.65)
