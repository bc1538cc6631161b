"""The airborne kinds: two-footed jumps and one-footed hops, on a pelvis curve that crouches,
pushes off, flies ballistically and absorbs the landing."""

from __future__ import annotations

import numpy as np

from .basics import STAND, ground_path, pick_value, time_grid
from .plan import FootPlan, Plan, quintic

GRAVITY = 9.81


def jump_pelvis_curve(
    t: np.ndarray, flights: list[tuple[float, float]], crouch: float, push: float, absorb: float, stand: float
) -> np.ndarray:
    """Pelvis height: stand, crouch, push up to take-off, ballistic flight, absorb, stand.

    Cubic Hermite pieces meet the flight parabola with equal position and velocity.
    """
    y = np.full_like(t, stand)

    def hermite(t0, t1, y0, v0, y1, v1, mask):
        h = t1 - t0
        s = (t[mask] - t0) / h
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        y[mask] = h00 * y0 + h10 * h * v0 + h01 * y1 + h11 * h * v1

    for t_off, t_land in flights:
        v0 = 0.5 * GRAVITY * (t_land - t_off)
        low = stand - crouch
        for t0, t1, y0, v0_, y1, v1 in (
            (t_off - push - 0.3, t_off - push, stand, 0.0, low, 0.0),
            (t_off - push, t_off, low, 0.0, stand, v0),
            (t_land, t_land + absorb, stand, -v0, low, 0.0),
            (t_land + absorb, t_land + absorb + 0.35, low, 0.0, stand, 0.0),
        ):
            hermite(t0, t1, y0, v0_, y1, v1, (t >= t0) & (t < t1))
        m = (t >= t_off) & (t < t_land)
        tau = t[m] - t_off
        y[m] = stand + v0 * tau - 0.5 * GRAVITY * tau * tau
    return y


def jump(rng, seconds, height=None, distance=None):
    """Two-footed jumps: crouch, take off, land and absorb; ``height`` of the pelvis rise (m)."""
    t, pad = time_grid(seconds)
    h, dist = pick_value(rng, height, (0.12, 0.3)), pick_value(rng, distance, (0.0, 0.5))
    flight = 2 * np.sqrt(2 * h / GRAVITY)
    cycle = flight + 1.7 + rng.uniform(0, 0.5)
    first = rng.uniform(0.5, 0.9)
    flights = [
        (first + k * cycle, first + k * cycle + flight)
        for k in range(int(np.ceil((seconds + 2) / cycle)) + 1)
    ]
    crouch = 0.12 + 0.3 * h
    pelvis = jump_pelvis_curve(t, flights, crouch, 0.3, 0.3, STAND)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    forward = np.zeros_like(t)
    for t_off, t_land in flights:
        forward += dist * quintic((t - (t_off - 0.3)) / (t_land - t_off + 0.6))
    root = ground_path(t, yaw, np.gradient(forward, t))
    stances = (
        [(t[0] - 1.0, flights[0][0])]
        + [(flights[k][1], flights[k + 1][0]) for k in range(len(flights) - 1)]
        + [(flights[-1][1], t[-1] + 1.0)]
    )
    feet = [FootPlan(s, stances, lateral=0.1, lift=0.08, follow_pelvis=True) for s in "lr"]
    arms = 1.0 + 0.6 * np.cos(np.pi * np.clip((pelvis - STAND) / max(h, 1e-3), -1, 1))
    plan = Plan(
        t=t,
        root_xz=root,
        yaw=yaw,
        pelvis_y=pelvis,
        feet=feet,
        pelvis_pitch=0.6 * (STAND - pelvis).clip(0, None),
        arm_swing={"l": 0.6 - 0.5 * arms, "r": 0.6 - 0.5 * arms},
        elbow_flex={"l": 0.2 + 0.2 * arms, "r": 0.2 + 0.2 * arms},
        pad=pad,
    )
    plan.takeoff_height = STAND
    return plan


def hop(rng, seconds, height=None, advance=None, side=None):
    """Repeated hops on one foot; the other leg is held bent behind."""
    t, pad = time_grid(seconds)
    h, step = pick_value(rng, height, (0.04, 0.1)), pick_value(rng, advance, (0.0, 0.35))
    support = side or str(rng.choice(["l", "r"]))
    free = "r" if support == "l" else "l"
    flight = 2 * np.sqrt(2 * h / GRAVITY)
    cycle = flight + rng.uniform(0.45, 0.65)
    flights = [
        (k * cycle, k * cycle + flight)
        for k in range(int(np.floor(t[0] / cycle)), int(np.ceil(t[-1] / cycle)) + 1)
    ]
    stand = STAND - 0.03
    pelvis = jump_pelvis_curve(t, flights, 0.05 + 0.3 * h, 0.15, 0.15, stand)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    speed = step / cycle
    root = ground_path(t, yaw, np.full_like(t, speed))
    stances = [(flights[k][1], flights[k + 1][0]) for k in range(len(flights) - 1)]
    sign = 1.0 if support == "l" else -1.0
    lifted = np.tile([-sign * 0.1, 0.0, -0.22], (len(t), 1))
    lifted[:, 1] = pelvis - 0.55
    feet = [
        FootPlan(support, stances, lateral=0.03, lift=0.04, follow_pelvis=True),
        FootPlan(free, [], free_target=lifted),
    ]
    plan = Plan(
        t=t,
        root_xz=root,
        yaw=yaw,
        pelvis_y=pelvis,
        feet=feet,
        pelvis_roll=np.full_like(t, -sign * 0.06),
        arm_abduction={"l": np.full_like(t, 0.35), "r": np.full_like(t, 0.35)},
        elbow_flex={"l": np.full_like(t, 0.6), "r": np.full_like(t, 0.6)},
        pad=pad,
    )
    plan.takeoff_height = stand
    return plan
