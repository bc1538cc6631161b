"""Resampling to the internal frame rate: slerp for rotations, linear for translations."""

from __future__ import annotations

import numpy as np

from .rotations import matrix_to_quat, quat_slerp, quat_to_matrix

# Frames per pass where a whole clip at once would allocate gigabytes of float64 temporaries (the
# frame limit allows ten hours): about 0.5 GB for 22 joints' rotations.
FRAME_CHUNK = 32_768


def frame_chunks(num_frames: int, chunk: int | None = None) -> list[tuple[int, int]]:
    """(start, stop) ranges covering ``num_frames`` frames in passes of at most ``chunk``
    (default :data:`FRAME_CHUNK`)."""
    chunk = chunk or FRAME_CHUNK
    return [(start, min(num_frames, start + chunk)) for start in range(0, num_frames, chunk)]


def resample_times(num_frames: int, fps_in: float, fps_out: float) -> np.ndarray:
    """Source-frame coordinates (fractional) of the output frames, covering the same time span."""
    if abs(fps_in - fps_out) <= 1e-4 * fps_out:  # e.g. BVH "Frame Time: 0.03333333"
        return np.arange(num_frames, dtype=np.float64)
    duration = (num_frames - 1) / fps_in
    # Tolerate frame times rounded in the file (a 1e-4 frame shortfall still counts as a frame).
    n_out = int(np.floor(duration * fps_out + 1e-4)) + 1
    return np.minimum(np.arange(n_out) * (fps_in / fps_out), num_frames - 1)


def resample_rotations(rot: np.ndarray, src_frames: np.ndarray) -> np.ndarray:
    """rot (T, ..., 3, 3) sampled at fractional frame coordinates by slerp (in float64, in passes of
    :data:`FRAME_CHUNK` output frames); the result has ``rot``'s dtype."""
    i0 = np.floor(src_frames).astype(int)
    i1 = np.minimum(i0 + 1, rot.shape[0] - 1)
    frac = src_frames - i0
    out = np.empty((len(src_frames), *rot.shape[1:]), rot.dtype)
    for start, stop in frame_chunks(len(src_frames)):
        q0 = matrix_to_quat(rot[i0[start:stop]].astype(np.float64, copy=False))
        q1 = matrix_to_quat(rot[i1[start:stop]].astype(np.float64, copy=False))
        t = np.broadcast_to(frac[start:stop].reshape((-1,) + (1,) * (q0.ndim - 2)), q0.shape[:-1])
        out[start:stop] = quat_to_matrix(quat_slerp(q0, q1, t))
    return out


def resample_linear(x: np.ndarray, src_frames: np.ndarray) -> np.ndarray:
    """Linear interpolation of per-frame values at fractional source frames."""
    i0 = np.floor(src_frames).astype(int)
    i1 = np.minimum(i0 + 1, x.shape[0] - 1)
    frac = (src_frames - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    return (1.0 - frac) * x[i0] + frac * x[i1]
