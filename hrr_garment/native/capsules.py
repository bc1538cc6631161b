"""The capsule body as the kernels take it: its arrays checked and converted, and the signed
distance of points to it (``push_frame.c``'s ``hrr_capsule_sdf``)."""

from __future__ import annotations

import ctypes

import numpy as np

MAX_CAPSULES = 64  # SDF_MAXC in push_out.h


def capsule_arrays(
    a: np.ndarray, b: np.ndarray, radii: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsule ends a, b and radii as float64 C arrays; more capsules than the kernels hold raise."""
    if np.shape(radii)[-1] > MAX_CAPSULES:
        raise ValueError(
            f"the native capsule kernels handle up to {MAX_CAPSULES} capsules, not {np.shape(radii)[-1]}"
        )
    return tuple(np.ascontiguousarray(x, np.float64) for x in (a, b, radii))


def capsule_sdf(
    lib: ctypes.CDLL, points: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray, threads: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hrr_garment.body.capsules.capsule_signed_distance` (distance, normal) in the kernel,
    for points (T, N, 3) against per-frame capsules a, b (T, C, 3)."""
    a, b, r = capsule_arrays(a, b, radii)
    p = np.ascontiguousarray(points, np.float64)
    t, n = p.shape[:2]
    dist, normal = np.empty((t, n)), np.empty((t, n, 3))
    lib.hrr_capsule_sdf(
        p.ctypes.data,
        t,
        n,
        a.ctypes.data,
        b.ctypes.data,
        r.ctypes.data,
        len(r),
        threads,
        dist.ctypes.data,
        normal.ctypes.data,
    )
    return dist, normal
