"""The body frame garment models learn in, and its inverse.

Garment frames are expressed relative to the pelvis: rotated by the pelvis heading (yaw only;
Y up, Z along the heading) and translated so that the origin follows the pelvis horizontally and
vertically, offset by the canonical rest pelvis height. A garment hangs from the waist and
shoulders, so this takes out what the body's own translation explains, crouching and standing
tall included: with a ground-level origin, a real clip whose pelvis rides 8 cm above the
procedural training motions put every predicted frame 8 cm too low (docs/results.md). At the
rest pelvis height the frame equals the ground-level heading frame, so the rest template is
unchanged in it.

The *ground-level* body frame (``ground=True``; FRAME_VERSION 1) keeps the origin on the ground
under the pelvis, so heights stay absolute: the dataset's quality statistics (hem swing) and the
dataset previews use it. Motion features use only the frame's rotation (:func:`body_heading`).

FRAME_VERSION is part of every trained model's settings key and the bundle format: models trained
in another frame are retrained, never silently misread.
"""

from __future__ import annotations

import numpy as np

from .motion import Motion
from .rotations import rotation_about_y, yaw_of
from .skeleton import REST_PELVIS_HEIGHT

FRAME_VERSION = 2  # 1: ground-level origin (heights absolute); 2: origin follows the pelvis height


def body_heading(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: the pelvis yaw (T,) and the body frame's rotation (T, 3, 3), body frame -> world."""
    yaw = yaw_of(motion.global_rotations[:, 0])
    return yaw, rotation_about_y(yaw)


def body_frame_origin(motion: Motion, ground: bool = False) -> np.ndarray:
    """(T, 3) world position of the body frame's origin (``ground``: of the ground-level frame)."""
    if ground:
        return motion.root_translation * np.array([1.0, 0.0, 1.0])
    return motion.root_translation - np.array([0.0, REST_PELVIS_HEIGHT, 0.0])


def to_body_frame(points: np.ndarray, motion: Motion, ground: bool = False) -> np.ndarray:
    """World points (T, N, 3) -> body frame (``ground``: the ground-level body frame)."""
    _, rot = body_heading(motion)
    return np.einsum("tni,tij->tnj", points - body_frame_origin(motion, ground)[:, None], rot)


def from_body_frame(points: np.ndarray, motion: Motion) -> np.ndarray:
    """Body-frame points (T, N, 3) -> world (float64); the inverse of :func:`to_body_frame`.
    Written out per coordinate (a rotation about Y leaves y alone): a stream calls it per frame,
    where the general (T, 3, 3) product costs several times more."""
    yaw = yaw_of(motion.global_rotations[:, 0])[:, None]
    c, s = np.cos(yaw), np.sin(yaw)
    origin = body_frame_origin(motion)
    out = np.empty(points.shape, np.float64)
    x, z = points[..., 0], points[..., 2]
    out[..., 0] = c * x + s * z + origin[:, 0:1]  # rotation_about_y(yaw) @ p + origin
    out[..., 1] = points[..., 1] + origin[:, 1:2]
    out[..., 2] = c * z - s * x + origin[:, 2:3]
    return out


def world_vertices(points: np.ndarray, motion: Motion) -> np.ndarray:
    """:func:`from_body_frame` rounded to float32, what inference hands on (the push-out, the
    caller): computed in the native kernel where compiled (frames in parallel, no temporaries)."""
    from .. import native

    lib = native.load_kernel()
    if lib is None:
        return from_body_frame(points, motion).astype(np.float32)
    return native.body_to_world(
        lib,
        points,
        yaw_of(motion.global_rotations[:, 0]),
        origin=body_frame_origin(motion),
        threads=native.default_threads(),
    )
