"""Resampling to the internal frame rate: slerp for rotations, linear for translations, and, for a
source recorded much faster than that rate, a low-pass filter first.

Keeping every fourth frame of a 120 fps capture keeps its marker noise as well: above the 15 Hz
that 30 fps can hold, it folds back into the motion (aliasing). Measured on the CMU clips of
subjects 01-09 against the Bandai-Namco library (30 fps as delivered), read by this package
(tools/studies/source_conventions.py): 24 % of the joints' velocity energy above 6 Hz against
0.6 %, and 1.6 % once the 120 fps frames are averaged over one output frame before they are
kept. So a source :data:`ANTI_ALIAS_RATIO` times faster than the output or more is resampled
through a triangle filter as wide as two output frames (each output frame a weighted average of
the source frames within one output frame of it): the convention of the capture's frame rate is
taken out, the motion stays.
"""

from __future__ import annotations

import numpy as np

from .rotations import matrix_to_quat, quat_slerp, quat_to_matrix

# Frames per pass where a whole clip at once would allocate gigabytes of float64 temporaries (the
# frame limit allows ten hours): about 0.5 GB for 22 joints' rotations.
FRAME_CHUNK = 32_768
# a source this many times faster than the output or more is low-pass filtered as it is resampled
ANTI_ALIAS_RATIO = 1.5


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


def kernel_width(fps_in: float, fps_out: float) -> float:
    """The half-width, in source frames, of the triangle each output frame averages over: 1 (the
    two neighbouring frames: interpolation) unless the source is :data:`ANTI_ALIAS_RATIO` times
    faster than the output or more, then one output frame (``fps_in / fps_out`` source frames)."""
    ratio = fps_in / fps_out
    return float(ratio) if ratio >= ANTI_ALIAS_RATIO else 1.0


def _triangle(src_frames: np.ndarray, width: float, num_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(source indices (T, K), weights (T, K)) of a triangle of half-width ``width`` centred on each
    fractional source frame; weights renormalised where the triangle runs past the clip's ends."""
    taps = int(np.ceil(2 * width)) + 1
    index = np.floor(src_frames - width).astype(int)[:, None] + 1 + np.arange(taps)
    weight = np.maximum(0.0, width - np.abs(index - src_frames[:, None]))
    weight[(index < 0) | (index >= num_frames)] = 0.0
    return np.clip(index, 0, num_frames - 1), weight / weight.sum(1, keepdims=True)


def _filtered_rotations(rot: np.ndarray, src_frames: np.ndarray, width: float) -> np.ndarray:
    """rot (T, ..., 3, 3) averaged over a triangle at each fractional frame: quaternions turned into
    the hemisphere of the nearest frame's, weighted, summed and normalised."""
    index, weight = _triangle(src_frames, width, rot.shape[0])
    out = np.empty((len(src_frames), *rot.shape[1:]), rot.dtype)
    chunk = max(1, FRAME_CHUNK // index.shape[1])
    for start, stop in frame_chunks(len(src_frames), chunk):
        q = matrix_to_quat(rot[index[start:stop]].astype(np.float64, copy=False))  # (t, K, ..., 4)
        w = weight[start:stop]
        centre = q[np.arange(stop - start), w.argmax(1)][:, None]
        sign = np.where((q * centre).sum(-1, keepdims=True) < 0, -1.0, 1.0)
        mean = (q * sign * w.reshape(w.shape + (1,) * (q.ndim - 2))).sum(1)
        out[start:stop] = quat_to_matrix(mean / np.linalg.norm(mean, axis=-1, keepdims=True))
    return out


def resample_rotations(rot: np.ndarray, src_frames: np.ndarray, width: float = 1.0) -> np.ndarray:
    """rot (T, ..., 3, 3) sampled at fractional frame coordinates by slerp (in float64, in passes of
    :data:`FRAME_CHUNK` output frames), or, with ``width`` over 1 (:func:`kernel_width`), averaged
    over a triangle that wide; the result has ``rot``'s dtype."""
    if width > 1.0:
        return _filtered_rotations(rot, src_frames, width)
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


def resample_linear(x: np.ndarray, src_frames: np.ndarray, width: float = 1.0) -> np.ndarray:
    """Linear interpolation of per-frame values at fractional source frames, or, with ``width`` over
    1 (:func:`kernel_width`), their average over a triangle that wide."""
    if width > 1.0:
        index, weight = _triangle(src_frames, width, x.shape[0])
        out = np.empty((len(src_frames), *x.shape[1:]), np.result_type(x.dtype, np.float32))
        for start, stop in frame_chunks(len(src_frames), max(1, FRAME_CHUNK // index.shape[1])):
            w = weight[start:stop]
            out[start:stop] = (x[index[start:stop]] * w.reshape(w.shape + (1,) * (x.ndim - 1))).sum(1)
        return out
    i0 = np.floor(src_frames).astype(int)
    i1 = np.minimum(i0 + 1, x.shape[0] - 1)
    frac = (src_frames - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    return (1.0 - frac) * x[i0] + frac * x[i1]
