"""Raw poses as a game engine hands them over each frame -> a :class:`Motion` whose frames are the poses.

Local (parent-relative) joint rotations in one of three forms, told apart by their last axes:

* (N, J, 4) unit quaternions, (x, y, z, w) by default: the order of glTF, Unity and Unreal
  (``quaternion_order="wxyz"`` for the other);
* (N, J, 3) axis-angle vectors (axis times the angle in radians);
* (N, J, 3, 3) rotation matrices (acting on column vectors).

Roots (N, 3) are pelvis positions in metres, Y up. The arrays are checked (shape, finite values,
quaternions not near zero, matrices that are rotations) and converted in one vectorised step: no
per-pose objects.
"""

from __future__ import annotations

import numpy as np

from ..errors import MotionError
from .limits import MAX_AXIS_ANGLE, ROTATION_TOLERANCE
from .motion import FPS, MAX_TRANSLATION_M, Motion
from .rotations import axis_angle_to_matrix, matrix_to_quat, quat_to_matrix, rotation_matrix_error
from .skeleton import CANONICAL

QUATERNION_ORDERS = ("xyzw", "wxyz")


def _real_array(values, name: str, source: str) -> np.ndarray:
    """``values`` as float64, refused by ``name`` when they are not real numbers (text, complex, objects)."""
    array = np.asarray(values)
    if array.dtype.kind not in "iuf":
        raise MotionError(source, f"{name} must be real numbers, got an array of {array.dtype}")
    return array.astype(np.float64, copy=False)


def rotations_to_matrices(
    rotations: np.ndarray, joints: int, quaternion_order: str = "xyzw", source: str = "pose"
) -> np.ndarray:
    """(N, J, 4 | 3 | 3 x 3) local rotations -> (N, J, 3, 3) float64 matrices, checked."""
    r = _real_array(rotations, "rotations", source)
    if r.ndim not in (3, 4) or r.shape[1] != joints or r.shape[2:] not in ((4,), (3,), (3, 3)):
        raise MotionError(
            source,
            f"rotations have shape {r.shape}: expected (N, {joints}, 4) quaternions, "
            f"(N, {joints}, 3) axis-angle or (N, {joints}, 3, 3) matrices",
        )
    if not np.isfinite(r).all():
        bad = np.argwhere(~np.isfinite(r.reshape(len(r), joints, -1)).all(-1))[0]
        raise MotionError(source, f"rotations are not finite (pose {bad[0]}, joint {bad[1]})")
    if r.shape[2:] == (4,):
        if quaternion_order not in QUATERNION_ORDERS:
            raise ValueError(f"quaternion_order must be one of {QUATERNION_ORDERS}, not {quaternion_order!r}")
        norm = np.linalg.norm(r, axis=-1)
        if (norm < 0.5).any() or (norm > 2.0).any():
            bad = np.argwhere((norm < 0.5) | (norm > 2.0))[0]
            raise MotionError(
                source,
                f"quaternion of pose {bad[0]}, joint {bad[1]} has length {norm[tuple(bad)]:.3g}, "
                "not a rotation (unit quaternions expected)",
            )
        wxyz = r[..., [3, 0, 1, 2]] if quaternion_order == "xyzw" else r
        return quat_to_matrix(wxyz)
    if r.shape[2:] == (3,):
        angle = np.linalg.norm(r, axis=-1)
        if (angle > MAX_AXIS_ANGLE).any():
            bad = np.argwhere(angle > MAX_AXIS_ANGLE)[0]
            raise MotionError(
                source,
                f"axis-angle of pose {bad[0]}, joint {bad[1]} turns {angle[tuple(bad)]:.3g} rad, "
                f"beyond {MAX_AXIS_ANGLE:.3g} (degrees given as radians, or a corrupt value)",
            )
        return axis_angle_to_matrix(r)
    error = rotation_matrix_error(r)
    if (error > ROTATION_TOLERANCE).any():
        bad = np.argwhere(error > ROTATION_TOLERANCE)[0]
        raise MotionError(source, f"the matrix of pose {bad[0]}, joint {bad[1]} is not a rotation")
    return r


def check_roots(roots: np.ndarray, poses: int, source: str = "pose") -> np.ndarray:
    """(N, 3) root positions, checked -> float64."""
    root = _real_array(roots, "roots", source)
    if root.shape != (poses, 3):
        raise MotionError(
            source, f"roots have shape {root.shape}, expected ({poses}, 3): one pelvis position per pose"
        )
    if not np.isfinite(root).all():
        raise MotionError(
            source, f"root of pose {int(np.argwhere(~np.isfinite(root).all(1))[0, 0])} is not finite"
        )
    reach = np.abs(root).max(1) if len(root) else root[:, 0]
    if (reach > MAX_TRANSLATION_M).any():
        bad = int(np.argmax(reach))
        raise MotionError(
            source,
            f"root of pose {bad} is {reach[bad]:.3g} m from the origin, beyond the "
            f"{MAX_TRANSLATION_M:g} m a pose may be (float32 vertices lose centimetres there)",
        )
    return root


def poses_to_motion(
    rotations: np.ndarray,
    roots: np.ndarray,
    quaternion_order: str = "xyzw",
    fps: float = FPS,
    source: str = "pose",
) -> Motion:
    """N canonical-skeleton poses -> an N-frame :class:`Motion` (22 joints, SMPL order)."""
    matrices = rotations_to_matrices(rotations, CANONICAL.num_joints, quaternion_order, source)
    # checked above (matrices) or rotations by construction (quaternions, axis-angles)
    return Motion(
        matrices.astype(np.float32),
        check_roots(roots, len(matrices), source),
        fps,
        source=source,
        check_rotations=False,
    )


def motion_to_poses(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of :func:`poses_to_motion`: a canonical motion as an engine would hand its frames
    over, local quaternions (T, 22, 4) x y z w and pelvis positions (T, 3), both float32."""
    wxyz = matrix_to_quat(np.asarray(motion.local_rotations, np.float64))
    return np.ascontiguousarray(wxyz[..., [1, 2, 3, 0]], np.float32), np.asarray(
        motion.root_translation, np.float32
    )
