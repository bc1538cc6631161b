"""What every procedural kind builds on: the padded time grid it plans on, drawing the parameters
left unpinned, integrating heading-frame velocities into a ground path, and the standing pelvis
height."""

from __future__ import annotations

import numpy as np

from ..motion import FPS
from ..skeleton import REST_PELVIS_HEIGHT

PAD_S = 1.5
STAND = REST_PELVIS_HEIGHT - 0.015  # knees very slightly soft


def pick_value(rng: np.random.Generator, value: float | None, span: tuple[float, float]) -> float:
    """``value`` if pinned, else a uniform draw from ``span`` (low, high)."""
    return float(rng.uniform(*span)) if value is None else float(value)


def time_grid(seconds: float) -> tuple[np.ndarray, int]:
    """Frame times (s) of a ``seconds`` clip padded by PAD_S either side, and the pad in frames."""
    pad = int(round(PAD_S * FPS))
    n = int(round(seconds * FPS)) + 2 * pad
    return (np.arange(n) - pad) / FPS, pad


def ground_path(
    t: np.ndarray, yaw: np.ndarray, forward: np.ndarray, sideways: np.ndarray | float = 0.0
) -> np.ndarray:
    """Integrate heading-frame velocities (m/s) along the yaw into a ground path (N, 2)."""
    sideways = np.broadcast_to(sideways, t.shape)
    vx = forward * np.sin(yaw) + sideways * np.cos(yaw)
    vz = forward * np.cos(yaw) - sideways * np.sin(yaw)
    dt = np.diff(t, prepend=t[0])
    return np.stack([np.cumsum(vx * dt), np.cumsum(vz * dt)], 1)
