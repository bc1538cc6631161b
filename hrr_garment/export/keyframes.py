"""Keyframe reduction for vertex animations with a stated error bound.

Exporters that store one morph target per keyframe (GLB) play the frames between two keyframes as
their linear interpolation. :func:`select_keyframes` picks keyframes greedily so that every frame
of the original animation is within ``tolerance`` metres (per vertex, Euclidean) of that
interpolation; ``tolerance=0`` keeps every frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Keyframes:
    """The frames kept for export and the worst error of interpolating between them."""

    frames: np.ndarray  # (K,) int, increasing, first 0 and last T-1
    max_error: float  # metres: the worst per-vertex distance of any frame from the interpolation


def interpolate(vertices: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """The animation (T, V, 3) that linear interpolation between keyframes ``keys`` plays back."""
    if len(keys) == 1:
        return np.repeat(vertices[keys[:1]], len(vertices), 0)
    t = np.arange(len(vertices))
    right = np.clip(np.searchsorted(keys, t, side="left"), 1, len(keys) - 1)
    left = right - 1
    s = ((t - keys[left]) / (keys[right] - keys[left]))[:, None, None]
    return (1 - s) * vertices[keys[left]] + s * vertices[keys[right]]


def _segment_error(vertices: np.ndarray, start: int, end: int) -> float:
    """Worst per-vertex distance of frames start+1..end-1 from the lerp of frames start and end."""
    if end - start < 2:
        return 0.0
    s = (np.arange(1, end - start) / (end - start))[:, None, None]
    lerp = (1 - s) * vertices[start] + s * vertices[end]
    return float(np.sqrt(((vertices[start + 1 : end] - lerp) ** 2).sum(-1)).max())


def select_keyframes(vertices: np.ndarray, tolerance: float, max_span: int = 60) -> Keyframes:
    """Greedy keyframes for ``vertices`` (T, V, 3): each segment grows until one more frame would put
    an in-between frame more than ``tolerance`` metres from the interpolation (or it spans
    ``max_span`` frames). The bound holds by construction; the count is not guaranteed minimal."""
    if tolerance < 0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance}")
    vertices = np.asarray(vertices, np.float64)
    t = len(vertices)
    if tolerance == 0 or t <= 2:
        return Keyframes(np.arange(t), 0.0)
    keys, start, worst = [0], 0, 0.0
    while start < t - 1:
        end, err = start + 1, 0.0
        while end + 1 < t and end + 1 - start <= max_span:
            trial = _segment_error(vertices, start, end + 1)
            if trial > tolerance:
                break
            end, err = end + 1, trial
        keys.append(end)
        worst = max(worst, err)
        start = end
    return Keyframes(np.array(keys), worst)
