"""The procedural motion kinds. Each builds a `Plan` from a seeded generator and its parameters.

Every parameter left as ``None`` is drawn from the kind's range with the seed, so a seed alone
gives a deterministic, varied clip; passing a value pins it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..motion import FPS
from ..skeleton import REST_PELVIS_HEIGHT
from .plan import FootPlan, Plan, quintic

PAD_S = 1.5
G = 9.81
STAND = REST_PELVIS_HEIGHT - 0.015  # knees very slightly soft


def _pick(rng: np.random.Generator, value: float | None, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi)) if value is None else float(value)


def _grid(seconds: float) -> tuple[np.ndarray, int]:
    pad = int(round(PAD_S * FPS))
    n = int(round(seconds * FPS)) + 2 * pad
    return (np.arange(n) - pad) / FPS, pad


def _stances(t: np.ndarray, period: float, duty: float, phase: float) -> list[tuple[float, float]]:
    """Stance intervals centred at phase + k * period covering the grid."""
    half = 0.5 * duty * period
    ks = np.arange(np.floor((t[0] - phase) / period) - 1, np.ceil((t[-1] - phase) / period) + 2)
    return [(phase + k * period - half, phase + k * period + half) for k in ks]


def _path(
    t: np.ndarray, yaw: np.ndarray, forward: np.ndarray, sideways: np.ndarray | float = 0.0
) -> np.ndarray:
    """Integrate heading-frame velocities (m/s) along the yaw into a ground path (N, 2)."""
    sideways = np.broadcast_to(sideways, t.shape)
    vx = forward * np.sin(yaw) + sideways * np.cos(yaw)
    vz = forward * np.cos(yaw) - sideways * np.sin(yaw)
    dt = np.diff(t, prepend=t[0])
    return np.stack([np.cumsum(vx * dt), np.cumsum(vz * dt)], 1)


@dataclass(frozen=True)
class Gait:
    """A stepping kind's numbers for :func:`_gait_plan` (metres, seconds, radians)."""

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


def _gait_plan(rng, t, pad, yaw, gait: Gait) -> Plan:
    """Shared by every stepping kind: alternating feet, arm swing opposite the legs."""
    period = gait.period
    phase = rng.uniform(0, period)
    w = 2 * np.pi * (t - phase) / period
    feet = [
        FootPlan(
            "l", _stances(t, period, gait.duty, phase), lateral=gait.lateral, lift=gait.lift, pivot=gait.pivot
        ),
        FootPlan(
            "r",
            _stances(t, period, gait.duty, phase + 0.5 * period),
            lateral=gait.lateral,
            lift=gait.lift,
            pivot=gait.pivot,
        ),
    ]
    bob, swing, flex, lean = gait.bob, gait.swing, gait.flex, gait.lean
    return Plan(
        t=t,
        root_xz=_path(t, yaw, gait.speed, gait.side_speed),
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


def _cadence(speed: float) -> float:
    """Steps per second for walking at ``speed`` m/s (step length at most 0.65 m: the feet stay flat
    in stance, so longer steps would need a deep crouch to keep both feet within reach)."""
    return max(1.4 + 0.45 * (abs(speed) - 0.6), abs(speed) / 0.65)


def idle(rng, seconds, sway=None, sway_hz=None, stance_width=None):
    """Stand with a slow sway and a wandering look."""
    t, pad = _grid(seconds)
    a, f = _pick(rng, sway, 0.015, 0.045), _pick(rng, sway_hz, 0.12, 0.3)
    width = _pick(rng, stance_width, 0.09, 0.13)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    phase = rng.uniform(0, 2 * np.pi)
    s = np.sin(2 * np.pi * f * t + phase)
    lateral = a * s
    root = np.stack([lateral * np.cos(yaw), -lateral * np.sin(yaw)], 1)
    whole = [(t[0] - 1.0, t[-1] + 1.0)]
    look = 0.3 * np.sin(2 * np.pi * 0.07 * t + rng.uniform(0, 6.3))
    return Plan(
        t=t,
        root_xz=root,
        yaw=yaw,
        pelvis_y=STAND - 0.01 - 0.01 * s * s,
        feet=[FootPlan("l", whole, lateral=width), FootPlan("r", whole, lateral=width)],
        pelvis_roll=-1.5 * a * s,
        head_yaw=look,
        arm_swing={"l": 0.05 * s, "r": -0.05 * s},
        elbow_flex={"l": 0.2 + 0.05 * s, "r": 0.2 - 0.05 * s},
        pad=pad,
    )


def walk(rng, seconds, speed=None):
    """Walk straight at ``speed`` m/s."""
    t, pad = _grid(seconds)
    v = _pick(rng, speed, 0.6, 1.8)
    period = 2.0 / _cadence(v)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    return _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
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
    t, pad = _grid(seconds)
    v = _pick(rng, speed, 2.0, 3.0)
    period = 2.0 / (2.7 + 0.2 * (v - 2.0))
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    # A high heel kick keeps the trailing foot within reach of the hip during early swing.
    return _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
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
    t, pad = _grid(seconds)
    v = _pick(rng, speed, 0.7, 1.5)
    rate = np.deg2rad(turn_rate if turn_rate is not None else rng.choice([-1, 1]) * rng.uniform(20, 60))
    wobble = rng.uniform(0.3, 0.8) * rate * np.sin(2 * np.pi * rng.uniform(0.05, 0.15) * t)
    yaw = rng.uniform(-np.pi, np.pi) + np.cumsum((rate + wobble) / FPS)
    return _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
            speed=v,
            side_speed=0.0,
            period=2.0 / _cadence(v),
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
    t, pad = _grid(seconds)
    rate = np.deg2rad(turn_rate if turn_rate is not None else rng.choice([-1, 1]) * rng.uniform(45, 90))
    ramp = quintic((t + 0.3) / 0.8) * quintic((seconds + 0.3 - t) / 0.8)
    yaw = rng.uniform(-np.pi, np.pi) + np.cumsum(rate * ramp / FPS)
    return _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
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
    t, pad = _grid(seconds)
    v = _pick(rng, speed, 0.2, 0.4) * (rng.choice([-1, 1]) if speed is None else 1.0)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    return _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
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
    t, pad = _grid(seconds)
    v = _pick(rng, speed, 0.4, 1.0)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    return _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
            speed=-v,
            side_speed=0.0,
            period=2.0 / _cadence(0.8 * v),
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
    t, pad = _grid(seconds)
    rps = _pick(rng, revolutions_per_s, 0.6, 1.3) * rng.choice([-1, 1])
    ramp = quintic((t + 0.2) / 1.0) * quintic((seconds + 0.2 - t) / 1.0)
    yaw = rng.uniform(-np.pi, np.pi) + np.cumsum(2 * np.pi * rps * ramp / FPS)
    plan = _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
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
    raise_ = _pick(rng, arm_raise, 0.6, 1.3)
    plan.arm_abduction = {s: raise_ * (0.3 + 0.7 * ramp) for s in "lr"}
    return plan


def dance(rng, seconds, sway=None, tempo_hz=None):
    """Step-touch from side to side with hip sway, torso twist and waving arms."""
    t, pad = _grid(seconds)
    a, f = _pick(rng, sway, 0.08, 0.2), _pick(rng, tempo_hz, 0.4, 0.7)
    yaw = rng.uniform(-np.pi, np.pi) + 0.5 * np.sin(2 * np.pi * 0.1 * t + rng.uniform(0, 6.3))
    w = 2 * np.pi * f * t
    plan = _gait_plan(
        rng,
        t,
        pad,
        yaw,
        Gait(
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


def _jump_curve(
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
        v0 = 0.5 * G * (t_land - t_off)
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
        y[m] = stand + v0 * tau - 0.5 * G * tau * tau
    return y


def jump(rng, seconds, height=None, distance=None):
    """Two-footed jumps: crouch, take off, land and absorb; ``height`` of the pelvis rise (m)."""
    t, pad = _grid(seconds)
    h, dist = _pick(rng, height, 0.12, 0.3), _pick(rng, distance, 0.0, 0.5)
    flight = 2 * np.sqrt(2 * h / G)
    cycle = flight + 1.7 + rng.uniform(0, 0.5)
    first = rng.uniform(0.5, 0.9)
    flights = [
        (first + k * cycle, first + k * cycle + flight)
        for k in range(int(np.ceil((seconds + 2) / cycle)) + 1)
    ]
    crouch = 0.12 + 0.3 * h
    pelvis = _jump_curve(t, flights, crouch, 0.3, 0.3, STAND)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    forward = np.zeros_like(t)
    for t_off, t_land in flights:
        forward += dist * quintic((t - (t_off - 0.3)) / (t_land - t_off + 0.6))
    root = _path(t, yaw, np.gradient(forward, t))
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
    t, pad = _grid(seconds)
    h, step = _pick(rng, height, 0.04, 0.1), _pick(rng, advance, 0.0, 0.35)
    support = side or str(rng.choice(["l", "r"]))
    free = "r" if support == "l" else "l"
    flight = 2 * np.sqrt(2 * h / G)
    cycle = flight + rng.uniform(0.45, 0.65)
    flights = [
        (k * cycle, k * cycle + flight)
        for k in range(int(np.floor(t[0] / cycle)), int(np.ceil(t[-1] / cycle)) + 1)
    ]
    stand = STAND - 0.03
    pelvis = _jump_curve(t, flights, 0.05 + 0.3 * h, 0.15, 0.15, stand)
    yaw = np.full_like(t, rng.uniform(-np.pi, np.pi))
    speed = step / cycle
    root = _path(t, yaw, np.full_like(t, speed))
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


KINDS: dict[str, Callable[..., Plan]] = {
    "idle": idle, "walk": walk, "run": run, "walk_curve": walk_curve, "turn_in_place": turn_in_place,
    "side_step": side_step, "walk_backward": walk_backward, "jump": jump, "hop": hop, "spin": spin, "dance": dance,
}  # fmt: skip
