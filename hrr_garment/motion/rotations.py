"""Vectorised rotation conversions for numpy arrays and torch tensors.

Every function takes arrays of any leading shape and works unchanged on ``numpy.ndarray`` and
``torch.Tensor`` (the backend is picked from the input), so the same code serves data loading
(numpy) and training (torch, differentiable).

Conventions
-----------
* Rotation matrices act on column vectors: ``v' = R @ v``.
* Quaternions are ``(w, x, y, z)``, unit length; ``q`` and ``-q`` are the same rotation and
  conversions return the representative with ``w >= 0``.
* Axis-angle is the axis scaled by the angle in radians, angle in ``[0, pi]``.
* 6D is the first two *columns* of the matrix, concatenated (Zhou et al. 2019).
"""

from __future__ import annotations

from typing import Any

import numpy as np

Array = Any  # numpy.ndarray or torch.Tensor

_EPS = 1e-8


def _is_torch(x: Array) -> bool:
    return type(x).__module__.startswith("torch")


def _xp(x: Array):
    if _is_torch(x):
        import torch

        return torch
    return np


def _stack(parts: list, axis: int) -> Array:
    return _xp(parts[0]).stack(parts, axis)


def _norm(x: Array) -> Array:
    """Euclidean norm over the last axis, keeping it."""
    return _xp(x).sqrt((x * x).sum(-1))[..., None]


def _one_hot_argmax(x: Array) -> Array:
    """One-hot mask (same dtype as x) of the argmax over the last axis."""
    if _is_torch(x):
        import torch

        return torch.nn.functional.one_hot(x.argmax(-1), x.shape[-1]).to(x.dtype)
    return np.eye(x.shape[-1], dtype=x.dtype)[x.argmax(-1)]


def normalize(v: Array) -> Array:
    """Unit vectors along the last axis (zero vectors stay zero)."""
    xp = _xp(v)
    n = _norm(v)
    return v / xp.where(n > _EPS, n, xp.ones_like(n))


# --- axis-angle <-> matrix ------------------------------------------------------------------------


def axis_angle_to_matrix(aa: Array) -> Array:
    """(..., 3) axis-angle -> (..., 3, 3) matrix (Rodrigues, exact near zero)."""
    xp = _xp(aa)
    theta2 = (aa * aa).sum(-1)
    small = theta2 < 1e-8
    # sqrt only of safe values: keeps torch gradients finite at the zero rotation.
    safe = xp.sqrt(xp.where(small, xp.ones_like(theta2), theta2))
    # sin(t)/t and (1-cos t)/t^2 with Taylor series where t is tiny.
    a = xp.where(small, 1.0 - theta2 / 6.0, xp.sin(safe) / safe)
    b = xp.where(small, 0.5 - theta2 / 24.0, (1.0 - xp.cos(safe)) / (safe * safe))
    x, y, z = aa[..., 0], aa[..., 1], aa[..., 2]
    zero = xp.zeros_like(x)
    k = _stack([_stack([zero, -z, y], -1), _stack([z, zero, -x], -1), _stack([-y, x, zero], -1)], -2)
    eye = xp.zeros_like(k)
    eye[..., 0, 0] = 1.0
    eye[..., 1, 1] = 1.0
    eye[..., 2, 2] = 1.0
    return eye + a[..., None, None] * k + b[..., None, None] * (k @ k)


def matrix_to_axis_angle(m: Array) -> Array:
    """(..., 3, 3) matrix -> (..., 3) axis-angle, angle in [0, pi]."""
    return quat_to_axis_angle(matrix_to_quat(m))


# --- quaternion <-> matrix ------------------------------------------------------------------------


def quat_to_matrix(q: Array) -> Array:
    """(..., 4) quaternion (w, x, y, z) -> (..., 3, 3) matrix. Input need not be normalised."""
    q = normalize(q)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rows = [
        _stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        _stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        _stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ]
    return _stack(rows, -2)


def matrix_to_quat(m: Array) -> Array:
    """(..., 3, 3) matrix -> (..., 4) quaternion with w >= 0.

    Computes the four algebraically equivalent candidates and keeps, per element, the one with the
    largest denominator, which is numerically stable for every rotation (Shepperd's method).
    """
    xp = _xp(m)
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    four = _stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    q_abs = xp.sqrt(xp.clip(four, 1e-12, None))
    candidates = _stack(
        [
            _stack([q_abs[..., 0] ** 2, m21 - m12, m02 - m20, m10 - m01], -1),
            _stack([m21 - m12, q_abs[..., 1] ** 2, m10 + m01, m02 + m20], -1),
            _stack([m02 - m20, m10 + m01, q_abs[..., 2] ** 2, m12 + m21], -1),
            _stack([m10 - m01, m20 + m02, m21 + m12, q_abs[..., 3] ** 2], -1),
        ],
        -2,
    ) / (2.0 * q_abs[..., :, None])
    q = (candidates * _one_hot_argmax(q_abs)[..., :, None]).sum(-2)
    q = normalize(q)
    return xp.where(q[..., :1] < 0, -q, q)


# --- quaternion <-> axis-angle --------------------------------------------------------------------


def axis_angle_to_quat(aa: Array) -> Array:
    """Axis-angle (..., 3) -> unit quaternions (..., 4), w first."""
    xp = _xp(aa)
    theta2 = (aa * aa).sum(-1)[..., None]
    small = theta2 < 1e-8
    safe = xp.sqrt(xp.where(small, xp.ones_like(theta2), theta2))
    k = xp.where(small, 0.5 - theta2 / 48.0, xp.sin(0.5 * safe) / safe)
    w = xp.where(small, 1.0 - theta2 / 8.0, xp.cos(0.5 * safe))
    return xp.concatenate([w, aa * k], -1)


def quat_to_axis_angle(q: Array) -> Array:
    """Unit quaternions (..., 4), w first -> axis-angle (..., 3)."""
    xp = _xp(q)
    q = normalize(q)
    q = xp.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s = _norm(v)
    w = q[..., :1]
    angle = 2.0 * (np.arctan2(s, w) if xp is np else xp.atan2(s, w))
    small = s < 1e-6
    ratio = xp.where(
        small, 2.0 / xp.where(small, w, xp.ones_like(w)), angle / xp.where(small, xp.ones_like(s), s)
    )
    return v * ratio


def quat_mul(a: Array, b: Array) -> Array:
    """Hamilton product a * b (apply b, then a)."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return _stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def quat_slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation, shortest path; ``t`` broadcasts against ``q[..., 0]``."""
    q0 = normalize(q0)
    q1 = normalize(q1)
    dot = (q0 * q1).sum(-1)
    q1 = np.where(dot[..., None] < 0, -q1, q1)
    dot = np.abs(dot).clip(-1.0, 1.0)
    t = np.asarray(t, dtype=q0.dtype)[..., None]
    theta = np.arccos(dot)[..., None]
    sin_theta = np.sin(theta)
    linear = sin_theta < 1e-6
    safe = np.where(linear, 1.0, sin_theta)
    w0 = np.where(linear, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(linear, t, np.sin(t * theta) / safe)
    return normalize(w0 * q0 + w1 * q1)


# --- 6D --------------------------------------------------------------------------------------------


def matrix_to_6d(m: Array) -> Array:
    """(..., 3, 3) -> (..., 6): first column then second column."""
    xp = _xp(m)
    cols = [m[..., :, 0], m[..., :, 1]]
    return xp.concatenate(cols, -1)


def sixd_to_matrix(d6: Array) -> Array:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt; exact inverse of :func:`matrix_to_6d`."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = normalize(a1)
    b2 = normalize(a2 - (b1 * a2).sum(-1)[..., None] * b1)
    b3 = cross(b1, b2)
    return _stack([b1, b2, b3], -1)


def cross(a: Array, b: Array) -> Array:
    """Cross product over the last axis."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return _stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], -1)


# --- Euler and helpers (numpy) ---------------------------------------------------------------------


def euler_to_matrix(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """(..., 3) angles in degrees applied in ``order`` (e.g. "ZYX": R = Rz @ Ry @ Rx), as in BVH."""
    from scipy.spatial.transform import Rotation

    shape = angles_deg.shape[:-1]
    rot = Rotation.from_euler(order.upper(), angles_deg.reshape(-1, 3), degrees=True)
    return rot.as_matrix().reshape(*shape, 3, 3)


def matrix_to_euler(m: np.ndarray, order: str) -> np.ndarray:
    """Inverse of :func:`euler_to_matrix` (degrees)."""
    from scipy.spatial.transform import Rotation

    shape = m.shape[:-2]
    return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_euler(order.upper(), degrees=True).reshape(*shape, 3)


def rotation_matrix_error(m: np.ndarray) -> np.ndarray:
    """How far (..., 3, 3) matrices are from rotations: the larger of max |M^T M - I| and
    |det M - 1| (0 for a rotation; zeros, scales and reflections score high), shape (...)."""
    error = np.abs(np.einsum("...ji,...jk->...ik", m, m) - np.eye(3)).max(axis=(-2, -1))
    # the determinant by cofactors: np.linalg.det's per-matrix LU is several times slower on 3 x 3
    det = (
        m[..., 0, 0] * (m[..., 1, 1] * m[..., 2, 2] - m[..., 1, 2] * m[..., 2, 1])
        - m[..., 0, 1] * (m[..., 1, 0] * m[..., 2, 2] - m[..., 1, 2] * m[..., 2, 0])
        + m[..., 0, 2] * (m[..., 1, 0] * m[..., 2, 1] - m[..., 1, 1] * m[..., 2, 0])
    )
    return np.maximum(error, np.abs(det - 1.0))


def rotation_about_y(yaw: Array) -> Array:
    """(...,) yaw angles in radians -> (..., 3, 3) rotations about +Y (numpy or torch)."""
    xp = _xp(yaw)
    c, s = xp.cos(yaw), xp.sin(yaw)
    z, o = xp.zeros_like(yaw), xp.ones_like(yaw)
    return _stack([_stack([c, z, s], -1), _stack([z, o, z], -1), _stack([-s, z, c], -1)], -2)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking direction(s) ``a`` onto ``b`` (..., 3) -> (..., 3, 3)."""
    a = normalize(a)
    b = normalize(b)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1, keepdims=True)
    c = (a * b).sum(-1, keepdims=True)
    angle = np.arctan2(s, c)
    # Opposite vectors: rotate by pi about any axis perpendicular to a.
    fallback = np.cross(a, np.array([1.0, 0.0, 0.0], dtype=a.dtype))
    fallback = np.where(
        np.linalg.norm(fallback, axis=-1, keepdims=True) < 1e-6,
        np.cross(a, np.array([0.0, 0.0, 1.0], dtype=a.dtype)),
        fallback,
    )
    axis = np.where(s > 1e-9, axis, np.where(c < 0, fallback, axis))
    return axis_angle_to_matrix(normalize(axis) * angle)


def kabsch(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Rotation R minimising sum w |R src_i - dst_i|^2; src, dst (..., N, 3) -> (..., 3, 3)."""
    if weights is None:
        weights = np.ones(src.shape[-2], dtype=src.dtype)
    h = np.einsum("...ni,...nj,n->...ij", src, dst, weights)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.swapaxes(vt, -1, -2) @ np.swapaxes(u, -1, -2)))
    fix = np.ones(h.shape[:-2] + (3,), dtype=h.dtype)
    fix[..., 2] = d
    return np.swapaxes(vt, -1, -2) @ (fix[..., :, None] * np.swapaxes(u, -1, -2))


def yaw_of(m: Array) -> Array:
    """Heading angle (radians, about +Y) of the rotated forward axis +Z (numpy or torch)."""
    fwd = m[..., :, 2]
    return _xp(m).arctan2(fwd[..., 0], fwd[..., 2])
