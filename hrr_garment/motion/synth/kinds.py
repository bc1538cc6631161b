"""The procedural motion kinds by name (`KINDS`), and standing idle. Each kind builds a `Plan` from a
seeded generator and its parameters (the stepping kinds live in :mod:`.stepping`, the airborne ones
in :mod:`.jumping`).

Every parameter left as ``None`` is drawn from the kind's range with the seed, so a seed alone
gives a deterministic, varied clip; passing a value pins it.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .basics import STAND, pick_value, time_grid
from .jumping import hop, jump
from .plan import FootPlan, Plan
from .stepping import dance, run, side_step, spin, turn_in_place, walk, walk_backward, walk_curve


def idle(rng, seconds, sway=None, sway_hz=None, stance_width=None):
    """Stand with a slow sway and a wandering look."""
    t, pad = time_grid(seconds)
    a, f = pick_value(rng, sway, (0.015, 0.045)), pick_value(rng, sway_hz, (0.12, 0.3))
    width = pick_value(rng, stance_width, (0.09, 0.13))
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


KINDS: dict[str, Callable[..., Plan]] = {
    "idle": idle, "walk": walk, "run": run, "walk_curve": walk_curve, "turn_in_place": turn_in_place,
    "side_step": side_step, "walk_backward": walk_backward, "jump": jump, "hop": hop, "spin": spin,
    "dance": dance,
}  # fmt: skip
