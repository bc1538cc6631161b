"""Motion memory: exponential moving averages of the body's velocities over a few time constants,
appended to the per-frame features (:mod:`.features`) so that the motion encoder's 10-frame
window (a third of a second) knows what the body did before it.

A loose skirt's hem still swings from a turn made a second ago; the window alone cannot see that
turn. For each time constant s (``seconds``) and each frame t, the memory holds

    m_t = a R_t m_{t-1} + (1 - a) u_t,   a = exp(-1 / (fps s)),   m_0 = u_0

where u_t are the frame's velocity features (the 20 feature joints' velocities and the root's, all
3-vectors in the body frame, and the yaw rate) and R_t turns last frame's body frame into this
frame's (the yaw step from the yaw-rate feature). So m_t is the exponentially weighted average of
the world velocities, seen from the body frame at t: like the features, it does not change when
the whole motion is moved or turned about the vertical axis (tested).

It is computed from the features alone, one frame after another, so offline clips, causal clips
and streams (:class:`MotionMemory`, carried per character) give the same values from the same
features. Models store their time constants (``CodeSpaceConfig.memory_seconds``); none gives the
124 plain features of models trained before it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.signal import lfilter

from .features import FEATURE_DIM, SLICE_T, SLICE_V, SLICE_W
from .rotations import rotation_about_y

VECTORS = (SLICE_V.stop - SLICE_V.start + SLICE_T.stop - SLICE_T.start) // 3  # 21: 20 joint velocities, the root's
MEMORY_WIDTH = 3 * VECTORS + 1  # values per time constant: the 3-vectors and the yaw rate


def feature_width(memory_seconds: Sequence[float]) -> int:
    """Features per frame with memory of ``memory_seconds`` time constants: 124 + 64 per constant."""
    return FEATURE_DIM + MEMORY_WIDTH * len(memory_seconds)


def check_memory_seconds(memory_seconds: Sequence[float]) -> tuple[float, ...]:
    """The time constants as a tuple of positive seconds, or a ValueError."""
    values = tuple(float(s) for s in memory_seconds)
    if any(not np.isfinite(s) or s <= 0 for s in values):
        raise ValueError(f"memory time constants must be positive seconds, got {list(memory_seconds)}")
    return values


class MotionMemory:
    """The memory of N motions advanced one frame at a time (streams: one row per character)."""

    def __init__(self, memory_seconds: Sequence[float], fps: float):
        self.seconds = check_memory_seconds(memory_seconds)
        self.decay = np.exp(-1.0 / (fps * np.array(self.seconds)))[:, None]  # (k, 1): broadcast over (N, k, 64)
        self.fps = float(fps)

    def start(self, features: np.ndarray) -> np.ndarray:
        """The state (N, k, 64) at a motion's first frame, from its features (N, 124)."""
        return np.repeat(_velocities(features)[:, None], len(self.seconds), 1)

    def step(self, state: np.ndarray, features: np.ndarray) -> np.ndarray:
        """The state (N, k, 64) one frame on, from the last state and this frame's features (N, 124)."""
        n, k = len(state), len(self.seconds)
        turn = rotation_about_y(-features[:, SLICE_W][:, 0].astype(np.float64) / self.fps)  # (N, 3, 3): last body frame -> this
        vectors = state[..., :-1].reshape(n, k, VECTORS, 3) @ np.swapaxes(turn, -1, -2)[:, None]
        carried = np.concatenate([vectors.reshape(n, k, -1), state[..., -1:]], -1)
        return self.decay * carried + (1.0 - self.decay) * _velocities(features)[:, None]

    @staticmethod
    def values(state: np.ndarray) -> np.ndarray:
        """The state as feature columns (N, k x 64), float32."""
        return state.reshape(len(state), -1).astype(np.float32)


def _velocities(features: np.ndarray) -> np.ndarray:
    """The remembered columns (N, 64) of features (N, 124): joint and root velocities, yaw rate."""
    return np.concatenate([features[:, SLICE_V], features[:, SLICE_T], features[:, SLICE_W]], 1).astype(np.float64)


def with_memory(features: np.ndarray, fps: float, memory_seconds: Sequence[float]) -> np.ndarray:
    """(T, 124) features of one motion -> (T, 124 + 64 k) with its memory appended; unchanged
    (the same array) without time constants. The recursion of :class:`MotionMemory` in closed
    form: the velocities turned into the first frame's body frame (the yaw steps summed), a linear
    filter there, turned back into each frame's body frame (the same values to rounding, tested)."""
    if not len(memory_seconds):
        return features
    memory = MotionMemory(memory_seconds, fps)
    heading = np.cumsum(features[:, SLICE_W][:, 0].astype(np.float64)) / fps  # yaw since frame 0 ...
    heading -= heading[0]  # ... frame 0's own step is before it
    to_first = rotation_about_y(heading)  # (T, 3, 3): frame t's body frame -> frame 0's
    u = _velocities(features)
    vectors = u[:, :-1].reshape(len(u), VECTORS, 3) @ np.swapaxes(to_first, -1, -2)
    first = np.concatenate([vectors.reshape(len(u), -1), u[:, -1:]], 1)
    out = np.empty((len(features), feature_width(memory.seconds)), np.float32)
    out[:, :FEATURE_DIM] = features
    for i, a in enumerate(memory.decay[:, 0]):
        smoothed = lfilter([1.0 - a], [1.0, -a], first, axis=0, zi=a * first[:1])[0]
        back = smoothed[:, :-1].reshape(len(u), VECTORS, 3) @ to_first
        cols = slice(FEATURE_DIM + i * MEMORY_WIDTH, FEATURE_DIM + (i + 1) * MEMORY_WIDTH)
        out[:, cols] = np.concatenate([back.reshape(len(u), -1), smoothed[:, -1:]], 1)
    return out
