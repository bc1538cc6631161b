"""Resampling to the internal frame rate: slerp for rotations, linear for translations."""

from __future__ import annotations

import numpy as np

from .rotations import matrix_to_quat, quat_slerp, quat_to_matrix


def resample_times(num_frames: int, fps_in: float, fps_out: float) -> np.ndarray:
    """Source-frame coordinates (fractional) of the output frames, covering the same time span."""
    if abs(fps_in - fps_out) <= 1e-4 * fps_out:  # e.g. BVH "Frame Time: 0.03333333"
        return np.arange(num_frames, dtype=np.float64)
    duration = (num_frames - 1) / fps_in
    # Tolerate frame times rounded in the file (a 1e-4 frame shortfall still counts as a frame).
    n_out = int(np.floor(duration * fps_out + 1e-4)) + 1
    return np.minimum(np.arange(n_out) * (fps_in / fps_out), num_frames - 1)


def resample_rotations(rot: np.ndarray, src_frames: np.ndarray) -> np.ndarray:
    """rot (T, ..., 3, 3) sampled at fractional frame coordinates by slerp."""
    i0 = np.floor(src_frames).astype(int)
    i1 = np.minimum(i0 + 1, rot.shape[0] - 1)
    frac = (src_frames - i0).reshape((-1,) + (1,) * (rot.ndim - 3))
    q = matrix_to_quat(rot)
    out = quat_slerp(q[i0], q[i1], np.broadcast_to(frac, q[i0].shape[:-1]))
    return quat_to_matrix(out)


def resample_linear(x: np.ndarray, src_frames: np.ndarray) -> np.ndarray:
    """Linear interpolation of per-frame values at fractional source frames."""
    i0 = np.floor(src_frames).astype(int)
    i1 = np.minimum(i0 + 1, x.shape[0] - 1)
    frac = (src_frames - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    return (1.0 - frac) * x[i0] + frac * x[i1]
