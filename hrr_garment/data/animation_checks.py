"""The checks an out.h5's contents pass as :func:`~.animation_file.read_animation_h5` reads them:
its frame rate, its arrays' types, shapes and finiteness, and the skeleton's motion (version 4).
(The garment's reach from the body is checked beside the format,
:func:`~.animation_file.farthest_from_body`, which the writer shares.)"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError


def checked_fps(path: Path, attrs: dict) -> float:
    """The file's frame rate attribute: one finite number in [1, 1000]."""
    if "fps" not in attrs:
        raise InputError(path, "missing the 'fps' attribute")
    value = np.asarray(attrs["fps"])
    if value.size != 1 or value.dtype.kind not in "iuf" or not 1 <= float(value.item()) <= 1000:
        raise InputError(
            path, f"the 'fps' attribute must be a frame rate in [1, 1000], got {str(attrs['fps'])[:40]!r}"
        )
    return float(value.item())


def check_arrays(
    path: Path,
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    per_frame: dict[str, np.ndarray],
    capsules: np.ndarray | None,
    radii: np.ndarray | None,
) -> None:
    """Raise :class:`InputError` naming ``path`` unless the arrays read are numbers of the layout's
    shapes, finite, one row per frame, and the capsules match their radii."""
    for key, arr in (("vertices", vertices), ("faces", faces), *per_frame.items()):
        if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "biuf":
            raise InputError(path, f"/{key} must hold numbers, got {getattr(arr, 'dtype', type(arr))}")
    if vertices.ndim != 3 or vertices.shape[2] != 3 or vertices.shape[0] < 1:
        raise InputError(path, f"/vertices must be (T, V, 3) with T >= 1, got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise InputError(path, f"/faces must be (F, 3), got {faces.shape}")
    if faces.min() < 0 or faces.max() >= vertices.shape[1]:
        raise InputError(path, f"/faces index vertices outside 0..{vertices.shape[1] - 1}")
    for key, arr in (
        ("vertices", vertices),
        ("body/joints", per_frame["body/joints"]),
        ("body/capsules", capsules),
        ("body/radii", radii),
    ):
        if arr is not None and arr.dtype.kind == "f" and not np.isfinite(arr).all():
            frames = np.flatnonzero(~np.isfinite(arr.reshape(len(arr), -1)).all(1))
            raise InputError(
                path, f"/{key} has non-finite values at frame {frames[0]} ({len(frames)} frames)"
            )
    t = vertices.shape[0]
    for key, arr in per_frame.items():
        if arr.ndim == 0 or arr.shape[0] != t:
            raise InputError(path, f"/{key} has {arr.shape[:1]} rows, /vertices has {t} frames")
    if per_frame["body/joints"].shape[1:] != (22, 3):
        raise InputError(path, f"/body/joints must be (T, 22, 3), got {per_frame['body/joints'].shape}")
    if capsules is not None and (
        capsules.shape[:1] != (t,)
        or capsules.shape[2:] != (2, 3)
        or radii is None
        or radii.shape != capsules.shape[1:2]
    ):
        raise InputError(
            path,
            f"/body/capsules {capsules.shape} and /body/radii "
            f"{None if radii is None else radii.shape} do not match (T, C, 2, 3) and (C,)",
        )


def checked_skeleton(path: Path, found: dict, frames: int) -> dict:
    """The skeleton's motion (version 4) as AnimationFile's fields, each checked; none where absent."""
    if not found:
        return {}
    shapes = {
        "body/rotations": (frames, 22, 4),
        "body/root_translation": (frames, 3),
        "body/offsets": (22, 3),
    }
    for key, shape in shapes.items():
        arr = found.get(key)
        if arr is None or arr.shape != shape or arr.dtype.kind != "f" or not np.isfinite(arr).all():
            raise InputError(
                path,
                f"/{key} must be finite numbers of shape {shape}, got "
                f"{None if arr is None else (arr.shape, str(arr.dtype))}",
            )
    return {
        "rotations": found["body/rotations"],
        "root_translation": found["body/root_translation"],
        "offsets": found["body/offsets"],
    }
