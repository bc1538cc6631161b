"""The project's native motion npz: canonical local rotation matrices, root translation, fps and
provenance, versioned (``format`` and ``version`` keys), written and read back checked."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import MotionError
from ..io_utils import atomic_path, require_suffix
from .bvh_motion import PLAUSIBLE_HEIGHT_M
from .limits import ROTATION_TOLERANCE, check_source_fps
from .motion import MAX_TRANSLATION_M, Motion, check_local_rotations
from .npz_read import numeric_array
from .skeleton import JOINT_NAMES, NUM_JOINTS

NATIVE_FORMAT = "hrr_garment.motion"
NATIVE_VERSION = 1


def save_motion(motion: Motion, path: str | Path) -> None:
    """The native npz: canonical local rotation matrices, root translation, fps, provenance (versioned)."""
    require_suffix(path, (".npz",), "a native motion")
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:  # a handle: numpy appends .npz to a name
        np.savez(
            fh,
            format=np.str_(NATIVE_FORMAT),
            version=np.int64(NATIVE_VERSION),
            local_rotations=motion.local_rotations.astype(np.float32),
            root_translation=motion.root_translation.astype(np.float64),
            fps=np.float64(motion.fps),
            source=np.str_(motion.source),
            source_skeleton=np.str_(motion.source_skeleton),
            source_height_m=np.float64(motion.source_height_m),
        )


def native_from_arrays(data: dict[str, np.ndarray], path: Path) -> Motion:
    """The motion a native npz's arrays (read from ``path``) hold, each checked."""
    version = data.get("version", np.int64(-1))
    if version.dtype.kind not in "iu" or version.size != 1 or int(version) != NATIVE_VERSION:
        raise MotionError(
            path,
            f"native motion format version {str(version)[:20]} is not supported (this build reads version "
            f"{NATIVE_VERSION})",
        )
    missing = [k for k in ("local_rotations", "root_translation", "fps") if k not in data]
    if missing:
        raise MotionError(path, f"missing keys {missing}")
    # float32, the precision a Motion keeps: hours of frames in float64 would be gigabytes
    rot = numeric_array(path, data, "local_rotations", bound=1.0 + ROTATION_TOLERANCE, dtype=np.float32)
    if rot.ndim != 4 or rot.shape[1:] != (NUM_JOINTS, 3, 3):
        raise MotionError(path, f"local_rotations has shape {rot.shape}; expected (T, {NUM_JOINTS}, 3, 3)")
    if rot.shape[0] == 0:
        raise MotionError(path, "the motion has no frames")
    check_local_rotations(rot, JOINT_NAMES, path)  # named after the file, not the clip's stored name
    root = numeric_array(path, data, "root_translation", bound=MAX_TRANSLATION_M)
    if root.shape != (rot.shape[0], 3):
        raise MotionError(path, f"root_translation has shape {root.shape}; expected ({rot.shape[0]}, 3)")
    fps = check_source_fps(data["fps"], path)
    height = (
        float(numeric_array(path, data, "source_height_m", bound=PLAUSIBLE_HEIGHT_M[1] * 2))
        if "source_height_m" in data
        else 1.7
    )
    if not height > 0:
        raise MotionError(path, f"source_height_m must be a positive height in metres, got {height:g}")
    return Motion(
        rot,
        root,
        fps,
        source=_text(path, data, "source", str(path)),
        source_skeleton=_text(path, data, "source_skeleton", "canonical"),
        source_height_m=height,
        check_rotations=False,
    )  # checked above, in passes


def _text(path: Path, data: dict[str, np.ndarray], key: str, default: str) -> str:
    """A string entry of the file at ``path`` (``default`` when absent); numbers and arrays are not names."""
    value = data.get(key)
    if value is None:
        return default
    if value.dtype.kind not in "US" or value.size != 1:
        raise MotionError(path, f"{key} must be a string, got a {value.dtype} array of shape {value.shape}")
    return str(value.item())[:1000]
