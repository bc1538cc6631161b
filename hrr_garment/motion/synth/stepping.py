"""The stepping kinds: walking (straight, curved, backwards), running, turning in place, side
steps, spins and dancing, each a :class:`~.gait.Gait` on its own heading curve."""

from __future__ import annotations

import numpy as np

from ..motion import FPS
from .basics import STAND, pick_value, time_grid
from .gait import Gait, gait_plan, walking_cadence
from .plan import quintic


def walk(rng, seconds, speed=None):
    """Walk straight at ``speed`` m/s."""
    t, pad = time_grid(seconds)
    v = pick_value(rng, speed, (0.6, 1.8))
    period = 2.0 / walking_cadence(v)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    return gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=v,
            side_speed=0.0,
            period=period,
            duty=0.58,
            lift=0.06 + 0.03 * v,
            lateral=0.095,
            bob=0.012 + 0.008 * v,
            swing=0.15 + 0.12 * v,
            flex=0.25,
            lean=0.04,
        ),
    )


def run(rng, seconds, speed=None):
    """Run straight at ``speed`` m/s."""
    t, pad = time_grid(seconds)
    v = pick_value(rng, speed, (2.0, 3.0))
    period = 2.0 / (2.7 + 0.2 * (v - 2.0))
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    # A high heel kick keeps the trailing foot within reach of the hip during early swing.
    return gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=v,
            side_speed=0.0,
            period=period,
            duty=0.36,
            lift=0.3 + 0.04 * v,
            lateral=0.07,
            bob=0.02,
            swing=0.5,
            flex=1.5,
            lean=0.15,
        ),
    )


def walk_curve(rng, seconds, speed=None, turn_rate=None):
    """Walk along a curve; ``turn_rate`` in degrees per second (sign gives the direction)."""
    t, pad = time_grid(seconds)
    v = pick_value(rng, speed, (0.7, 1.5))
    rate = np.deg2rad(turn_rate if turn_rate is not None else rng.choice([-1, 1]) * rng.uniform(20, 60))
    wobble = rng.uniform(0.3, 0.8) * rate * np.sin(2 * np.pi * rng.uniform(0.05, 0.15) * t)
    yaw = rng.uniform(-np.pi, np.pi) + np.cumsum((rate + wobble) / FPS)
    return gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=v,
            side_speed=0.0,
            period=2.0 / walking_cadence(v),
            duty=0.58,
            lift=0.07 + 0.03 * v,
            lateral=0.095,
            bob=0.015,
            swing=0.2 + 0.1 * v,
            flex=0.25,
            lean=0.04,
        ),
    )


def turn_in_place(rng, seconds, turn_rate=None):
    """Turn on the spot with small steps; ``turn_rate`` in degrees per second."""
    t, pad = time_grid(seconds)
    rate = np.deg2rad(turn_rate if turn_rate is not None else rng.choice([-1, 1]) * rng.uniform(45, 90))
    ramp = quintic((t + 0.3) / 0.8) * quintic((seconds + 0.3 - t) / 0.8)
    yaw = rng.uniform(-np.pi, np.pi) + np.cumsum(rate * ramp / FPS)
    return gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=0.0,
            side_speed=0.0,
            period=1.2,
            duty=0.66,
            lift=0.05,
            lateral=0.1,
            bob=0.006,
            swing=0.05,
            flex=0.25,
        ),
    )


def side_step(rng, seconds, speed=None):
    """Step sideways; positive ``speed`` moves to the character's left."""
    t, pad = time_grid(seconds)
    v = pick_value(rng, speed, (0.2, 0.4)) * (rng.choice([-1, 1]) if speed is None else 1.0)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    return gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=0.0,
            side_speed=v,
            period=1.3,
            duty=0.7,
            lift=0.06,
            lateral=0.13,
            bob=0.008,
            swing=0.05,
            flex=0.25,
        ),
    )


def walk_backward(rng, seconds, speed=None):
    """Walk backwards at ``speed`` m/s."""
    t, pad = time_grid(seconds)
    v = pick_value(rng, speed, (0.4, 1.0))
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    return gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=-v,
            side_speed=0.0,
            period=2.0 / walking_cadence(0.8 * v),
            duty=0.66,
            lift=0.07,
            lateral=0.095,
            bob=0.01,
            swing=0.1,
            flex=0.3,
            lean=0.02,
        ),
    )


def spin(rng, seconds, revolutions_per_s=None, arm_raise=None):
    """Twirl on the spot with quick pivoting steps and the arms out (makes skirts flare)."""
    t, pad = time_grid(seconds)
    rps = pick_value(rng, revolutions_per_s, (0.6, 1.3)) * rng.choice([-1, 1])
    ramp = quintic((t + 0.2) / 1.0) * quintic((seconds + 0.2 - t) / 1.0)
    yaw = rng.uniform(-np.pi, np.pi) + np.cumsum(2 * np.pi * rps * ramp / FPS)
    plan = gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=0.0,
            side_speed=0.0,
            period=0.6,
            duty=0.6,
            lift=0.05,
            lateral=0.08,
            bob=0.006,
            swing=0.05,
            flex=0.4,
            pivot=True,
        ),
    )
    raise_ = pick_value(rng, arm_raise, (0.6, 1.3))
    plan.arm_abduction = {s: raise_ * (0.3 + 0.7 * ramp) for s in "lr"}
    return plan


def dance(rng, seconds, sway=None, tempo_hz=None):
    """Step-touch from side to side with hip sway, torso twist and waving arms."""
    t, pad = time_grid(seconds)
    a, f = pick_value(rng, sway, (0.08, 0.2)), pick_value(rng, tempo_hz, (0.4, 0.7))
    yaw = rng.uniform(-np.pi, np.pi) + 0.5 * np.sin(2 * np.pi * 0.1 * t + rng.uniform(0, 6.3))
    w = 2 * np.pi * f * t
    plan = gait_plan(
        rng,
        t,
        pad,
        yaw=yaw,
        gait=Gait(
            speed=0.0,
            side_speed=2 * np.pi * f * a * np.cos(w),
            period=1.0 / f,
            duty=0.7,
            lift=0.06,
            lateral=0.11,
            bob=0.01,
            swing=0.1,
            flex=0.5,
        ),
    )
    plan.pelvis_roll = 0.15 * np.sin(w + 0.5)
    plan.pelvis_y = STAND - 0.04 + 0.025 * np.cos(4 * np.pi * f * t)
    plan.spine_twist = 0.25 * np.sin(w + rng.uniform(0, 6.3))
    plan.arm_abduction = {"l": 0.9 + 0.7 * np.sin(w), "r": 0.9 - 0.7 * np.sin(w + 0.4)}
    plan.arm_swing = {"l": 0.5 * np.sin(2 * w), "r": 0.5 * np.cos(2 * w)}
    plan.elbow_flex = {"l": 0.8 + 0.5 * np.sin(w), "r": 0.8 + 0.5 * np.cos(w)}
    return plan
