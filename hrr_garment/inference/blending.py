"""From per-window latents to per-frame latents.

Offline, each frame's latent is the weighted mean of the windows that cover it, with weights that
peak at window centres (sin^2), so a change of source between windows is a cross-fade, continuous
in position and velocity. Causal, frame t takes the last frame of the window ending at t, and a
change of source (mode, or retrieved clip) is removed by inertialization: the offset between the
previous output and the new source (and between their velocities) decays to zero over ``blend``
frames with a quintic that has zero velocity and acceleration at its end.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .gate import WindowChoice


def window_weights(size: int) -> np.ndarray:
    """Blend weight of each position in a window: sin^2, highest at the centre, never zero."""
    return np.sin(np.pi * (np.arange(size) + 0.5) / size) ** 2


def blend_windows(latents: np.ndarray, frames: int) -> np.ndarray:
    """Per-frame weighted mean of overlapping windows: latents (N, W, ...) with window i covering
    frames i .. i + W - 1 -> (frames, ...)."""
    n, w = latents.shape[:2]
    weights = window_weights(w)
    total = np.zeros((frames, *latents.shape[2:]), np.float64)
    norm = np.zeros(frames)
    for k in range(w):
        total[k:k + n] += weights[k] * latents[:, k]
        norm[k:k + n] += weights[k]
    return (total / norm.reshape(-1, *([1] * (latents.ndim - 2)))).astype(np.float32)


@dataclass
class Inertializer:
    """Removes jumps when the latent source switches: keeps the offset (and its velocity) between
    the last output and the new source, and lets it decay to zero over ``frames`` frames along a
    quintic with zero velocity and acceleration at the end (continuous position and velocity)."""

    frames: int = 6
    _prev: np.ndarray | None = None
    _prev_vel: np.ndarray | None = None
    _offset: np.ndarray | None = None
    _offset_vel: np.ndarray | None = None
    _age: int = 0
    _source: tuple = field(default=(None,))
    _prev_target: np.ndarray | None = None

    def step(self, target: np.ndarray, source: tuple) -> np.ndarray:
        """target: this frame's latent from ``source`` (a hashable id of where it came from)."""
        target_vel = target - self._prev_target if self._prev_target is not None and source == self._source else None
        if self._prev is not None and source != self._source:
            vel = target_vel if target_vel is not None else np.zeros_like(target)
            prev_vel = self._prev_vel if self._prev_vel is not None else np.zeros_like(target)
            self._offset = self._prev + prev_vel - target  # where the old motion would have gone
            self._offset_vel = prev_vel - vel
            self._age = -1
        out = target.copy()
        if self._offset is not None:
            self._age += 1
            t = min(1.0, self._age / self.frames)
            if t < 1.0:
                x0, v0, T = self._offset, self._offset_vel * self.frames, 1.0
                # quintic from (x0, v0, a0 = 0) to (0, 0, 0) on [0, 1]
                a = -(6 * x0 + 3 * v0 * T)
                b = 15 * x0 + 8 * v0 * T
                c = -(10 * x0 + 6 * v0 * T)
                out += x0 + v0 * t + c * t**3 + b * t**4 + a * t**5
            else:
                self._offset = None
        self._prev_vel = out - self._prev if self._prev is not None else np.zeros_like(out)
        self._prev, self._source, self._prev_target = out, source, target
        return out


def source_id(retrieved: bool, source: np.ndarray) -> tuple:
    """Consecutive causal windows from one retrieved clip advance by one frame each: same id."""
    return ("regression",) if not retrieved else ("retrieval", int(source[0]), int(source[1]))


def causal_latents(choice: WindowChoice, blend: int = 6) -> np.ndarray:
    """Frame t's latent = the last frame of the window ending at t, made continuous across source
    changes by :class:`Inertializer`. ``choice`` has one window per frame."""
    inert = Inertializer(blend)
    out = np.empty((len(choice.latents), *choice.latents.shape[2:]), np.float32)
    for t in range(len(out)):
        src = choice.source[t] - np.array([0, t]) if choice.retrieved[t] else choice.source[t]
        out[t] = inert.step(choice.latents[t, -1].astype(np.float64), source_id(bool(choice.retrieved[t]), src))
    return out
