"""ctypes glue of the motion kernels (``features.c``): forward kinematics, causal motion features
and body-frame points into the world, for :mod:`hrr_garment.motion` (library from
:func:`hrr_garment.native.load_kernel`)."""

from __future__ import annotations

import ctypes

import numpy as np


def forward_kinematics(
    lib: ctypes.CDLL, local_rot: np.ndarray, root_pos: np.ndarray, offsets: np.ndarray, parents
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hrr_garment.motion.skeleton.forward_kinematics` in the kernel, for numpy motions:
    local rotations (T, J, 3, 3), root positions (T, 3), offsets (J, 3) -> float64 global rotations
    (T, J, 3, 3) and positions (T, J, 3)."""
    local = np.ascontiguousarray(local_rot, np.float32)
    root = np.ascontiguousarray(root_pos, np.float64)
    off = np.ascontiguousarray(offsets, np.float64)
    par = np.ascontiguousarray(parents, np.int32)
    t, j = local.shape[:2]
    g_rot, g_pos = np.empty((t, j, 3, 3)), np.empty((t, j, 3))
    lib.hrr_forward_kinematics(
        local.ctypes.data,
        root.ctypes.data,
        t,
        j,
        off.ctypes.data,
        par.ctypes.data,
        g_rot.ctypes.data,
        g_pos.ctypes.data,
    )
    return g_rot, g_pos


def causal_features(lib: ctypes.CDLL, g_rot: np.ndarray, g_pos: np.ndarray, joints, fps: float) -> np.ndarray:
    """Motion features (T, 6 F + 4) of every frame from it and the frame before (frame 0 from
    itself: zero velocities), from global rotations (T, J, 3, 3) and positions (T, J, 3): what
    :func:`hrr_garment.motion.features.causal_features` computes in numpy."""
    rot, pos = np.ascontiguousarray(g_rot, np.float64), np.ascontiguousarray(g_pos, np.float64)
    idx = np.ascontiguousarray(joints, np.int32)
    t, j = rot.shape[:2]
    out = np.empty((t, 6 * len(idx) + 4), np.float32)
    lib.hrr_causal_features(
        rot.ctypes.data, pos.ctypes.data, t, j, idx.ctypes.data, len(idx), float(fps), out.ctypes.data
    )
    return out


def body_to_world(
    lib: ctypes.CDLL, points: np.ndarray, yaw: np.ndarray, origin: np.ndarray, threads: int = 1
) -> np.ndarray:
    """:func:`hrr_garment.motion.frame.from_body_frame` in the kernel, into float32: body-frame
    points (T, N, 3), each frame's yaw (T,) and body-frame origin (T, 3) -> world points (T, N, 3)."""
    p = np.ascontiguousarray(points, np.float32)
    turn = np.ascontiguousarray(np.stack([np.cos(yaw), np.sin(yaw)], 1), np.float64)
    o = np.ascontiguousarray(origin, np.float64)
    out = np.empty(p.shape, np.float32)
    lib.hrr_body_to_world(
        p.ctypes.data, p.shape[0], p.shape[1], turn.ctypes.data, o.ctypes.data, threads, out.ctypes.data
    )
    return out
