"""Bounds on motion input: how much work a file may ask for, and which values are plausible.

A motion file decides how much memory and time loading it costs (a frame count, a frame time, a
declared array shape, a compressed payload), so each of those has an explicit limit here, checked
before the work is done, with a message that names the limit and how to raise it. The defaults
leave real capture far inside them: ten hours at 30 fps, a 2 GiB npz payload.

Environment overrides (for users with genuinely larger inputs): ``HRR_MAX_FRAMES`` (frames after
resampling) and ``HRR_MAX_NPZ_BYTES`` (an npz's decompressed arrays, in bytes).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import MotionError

MAX_FRAMES = 1_080_000  # frames after resampling: ten hours at 30 fps
MAX_NPZ_BYTES = 2 << 30  # decompressed size of an npz's arrays
MAX_BVH_DEPTH = 64  # joints nested inside one another (a human hierarchy is under 15 deep)
MAX_JOINTS = 1024  # joints in a hierarchy or a skin (hands and face rigs stay in the hundreds)
MAX_BVH_VALUE = 1.0e6  # |offset|, |position| in file units and |angle| in degrees
MAX_AXIS_ANGLE = 8 * np.pi  # radians: poses stay near pi; more is a scaled or corrupt rotation
ROTATION_TOLERANCE = 1e-3  # how far a given rotation matrix may be from one (rotations.rotation_matrix_error)
MAX_ROOT_SPEED = 100.0  # m/s between two frames at the canonical rate: beyond it the root teleports
MIN_SOURCE_FPS = 1.0  # a frame time over a second is a unit mistake (e.g. milliseconds)
MAX_SOURCE_FPS = 1000.0  # above this a "frame rate" is a unit mistake, not a capture rate


def _limit(name: str, default: int) -> int:
    value = os.environ.get(name)
    if value is None:
        return default
    try:
        parsed = int(value)
    except ValueError:
        raise MotionError(name, f"must be a whole number, got {value!r}") from None
    if parsed <= 0:
        raise MotionError(name, f"must be positive, got {parsed}")
    return parsed


def max_frames() -> int:
    """Frames a clip may have after resampling (``HRR_MAX_FRAMES`` or ``MAX_FRAMES``)."""
    return _limit("HRR_MAX_FRAMES", MAX_FRAMES)


def max_npz_bytes() -> int:
    """Bytes an npz's arrays may take uncompressed (``HRR_MAX_NPZ_BYTES`` or ``MAX_NPZ_BYTES``)."""
    return _limit("HRR_MAX_NPZ_BYTES", MAX_NPZ_BYTES)


def check_frame_budget(path: str | Path, num_frames: int, fps_in: float, fps_out: float) -> None:
    """Refuse a clip whose resampled length is over the frame limit, before allocating it."""
    out = int((num_frames - 1) / fps_in * fps_out) + 1
    limit = max_frames()
    if out > limit:
        raise MotionError(
            path,
            f"{num_frames} frames at {fps_in:g} fps resample to {out:,} frames at {fps_out:g} fps, "
            f"over the limit of {limit:,} (set HRR_MAX_FRAMES to raise it)",
        )


def check_root_speed(path: str | Path, root: np.ndarray, fps: float) -> None:
    """Refuse a root that jumps faster than a body can move (a unit mistake, a corrupt frame)."""
    if len(root) < 2:
        return
    speed = np.linalg.norm(np.diff(root, axis=0), axis=1) * fps
    worst = int(np.argmax(speed))
    if speed[worst] > MAX_ROOT_SPEED:
        raise MotionError(
            path,
            f"the root moves {speed[worst]:.3g} m/s between frames {worst} and {worst + 1} "
            f"(more than {MAX_ROOT_SPEED:g} m/s: a wrong unit or a corrupt frame)",
        )


def check_source_fps(value: float, path: str | Path) -> float:
    """A file's frame rate as given by the user: finite, positive and plausible, or a clear error."""
    arr = np.asarray(value)
    if arr.size != 1 or arr.dtype.kind not in "iuf":
        raise MotionError(path, f"frame rate must be one real number, got {str(value)[:40]!r}")
    rate = float(arr.item())
    if not (np.isfinite(rate) and MIN_SOURCE_FPS <= rate <= MAX_SOURCE_FPS):
        raise MotionError(
            path,
            f"frame rate must be a finite number of frames per second in [{MIN_SOURCE_FPS:g}, "
            f"{MAX_SOURCE_FPS:g}], got {rate:g}",
        )
    return rate
