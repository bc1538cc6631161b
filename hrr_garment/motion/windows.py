"""Sliding windows over per-frame arrays, the one place for them: every window of a clip
(training), every window that holds a frame of it, its ends repeated (offline inference), or the
window ending at each frame (causal inference).

All are views or one copy of the frames; a window holds W consecutive frames, window i covering
frames i .. i + W - 1 (training), i - W + 1 .. i (offline) or t - W + 1 .. t (causal, window t).
"""

from __future__ import annotations

import numpy as np

from ..errors import MotionError

DEFAULT_WINDOW = 10


def sequence_windows(frames: np.ndarray, window: int) -> np.ndarray:
    """(T, ...) -> (T - W + 1, W, ...): every window of consecutive frames (a view, no copy)."""
    return np.moveaxis(np.lib.stride_tricks.sliding_window_view(frames, window, axis=0), -1, 1)


def windows(
    features: np.ndarray, size: int = DEFAULT_WINDOW, stride: int = 1, source: str = "motion"
) -> np.ndarray:
    """(N, size, D) overlapping windows, N = (T - size) // stride + 1 (a view, no copy); a clip
    shorter than one window is an error that names ``source``."""
    if features.shape[0] < size:
        raise MotionError(
            source, f"clip has {features.shape[0]} frames, shorter than one window of {size} frames"
        )
    return sequence_windows(features, size)[::stride]


def covering_windows(features: np.ndarray, size: int) -> np.ndarray:
    """(T, F) -> (T + W - 1, W, F): every window that holds a frame of the clip, window i covering
    frames i - W + 1 .. i, the first frame repeated before the start and the last after the end (a
    view of the padded frames). Offline, every frame is then the mean of all W window positions:
    with the clip's own windows alone, a frame within a window of either end took their leading or
    trailing positions only, and the cloth of a body standing still drifted 12-19 mm a frame
    there (the decoder's course along a window is not flat). The start is a stream's (its first
    frame's window repeated); the end holds the last frame's features as they are, moving or not."""
    pad = size - 1
    padded = np.concatenate([np.repeat(features[:1], pad, 0), features, np.repeat(features[-1:], pad, 0)])
    return sequence_windows(padded, size)


def causal_windows(features: np.ndarray, size: int, view: bool = False) -> np.ndarray:
    """(T, F) -> (T, W, F): window t holds frames t-W+1 .. t, frame 0 repeated before the start;
    contiguous, or with ``view`` a view of the padded frames (W times less memory)."""
    padded = np.concatenate([np.repeat(features[:1], size - 1, 0), features])
    windows = sequence_windows(padded, size)
    return windows if view else np.ascontiguousarray(windows)
