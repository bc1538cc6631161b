"""AMASS-style npz motion: SMPL / SMPL-H / SMPL-X pose widths, Z up, read as a canonical motion
(the first 22 joints are the SMPL body's) and written from one."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import MotionError
from ..io_utils import atomic_path, require_suffix
from .limits import MAX_AXIS_ANGLE, check_frame_budget, check_source_fps
from .motion import FPS, MAX_TRANSLATION_M, Motion
from .native_file import NATIVE_FORMAT
from .npz_read import numeric_array
from .resample import frame_chunks, kernel_width, resample_linear, resample_rotations, resample_times
from .retarget import ground_align
from .rotations import axis_angle_to_matrix, matrix_to_axis_angle
from .skeleton import NUM_JOINTS

# Z-up (AMASS) to Y-up: rotate -90 degrees about X, so +Z becomes +Y and +Y becomes -Z.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
AMASS_WIDTHS = {72: "smpl", 156: "smplh", 165: "smplx"}


def load_amass(
    path: Path,
    data: dict[str, np.ndarray],
    ground: bool = True,
    fps: float = FPS,
    source_fps: float | None = None,
) -> Motion:
    """AMASS-style npz: the first 22 joints of ``poses`` are SMPL body joints, Z up. ``poses`` is
    (T, 72|156|165) or per joint (T, 24|52|55, 3); ``source_fps`` stands in for a missing rate key."""
    missing = [k for k in ("poses", "trans") if k not in data]
    rate_key = next((k for k in ("mocap_framerate", "mocap_frame_rate") if k in data), None)
    if missing:
        raise MotionError(
            path,
            f"missing keys {missing} (AMASS-style npz needs poses, trans and the frame rate; native npz "
            f"files carry format={NATIVE_FORMAT!r})",
        )
    if rate_key is None and source_fps is None:
        raise MotionError(
            path,
            "no frame rate: the file has no mocap_framerate (or mocap_frame_rate) key; "
            "give the rate it was captured at with --fps (e.g. --fps 120)",
        )
    poses = numeric_array(path, data, "poses", bound=MAX_AXIS_ANGLE)
    trans = numeric_array(path, data, "trans", bound=MAX_TRANSLATION_M)
    if poses.ndim == 3 and poses.shape[2] == 3 and poses.shape[1] * 3 in AMASS_WIDTHS:
        poses = poses.reshape(poses.shape[0], poses.shape[1] * 3)  # per-joint axis-angle
    if poses.ndim != 2 or poses.shape[1] not in AMASS_WIDTHS:
        raise MotionError(
            path,
            f"poses has shape {poses.shape}; expected (T, 72|156|165) or (T, 24|52|55, 3) "
            "for SMPL, SMPL-H or SMPL-X",
        )
    if trans.shape != (poses.shape[0], 3):
        raise MotionError(
            path, f"trans has shape {trans.shape}; expected ({poses.shape[0]}, 3) to match poses"
        )
    if poses.shape[0] == 0:
        raise MotionError(path, "the motion has no frames")
    rate = source_fps if source_fps is not None else check_source_fps(data[rate_key], f"{path}: {rate_key}")
    # float32 as the Motion keeps them, converted in passes: hours of frames stay within memory
    local = np.empty((poses.shape[0], NUM_JOINTS, 3, 3), np.float32)
    for a, b in frame_chunks(poses.shape[0]):
        part = axis_angle_to_matrix(poses[a:b, : NUM_JOINTS * 3].reshape(-1, NUM_JOINTS, 3))
        part[:, 0] = Z_UP_TO_Y_UP @ part[:, 0]
        local[a:b] = part
    root = trans @ Z_UP_TO_Y_UP.T
    check_frame_budget(path, poses.shape[0], rate, fps_out=fps)
    frames = resample_times(poses.shape[0], rate, fps)
    width = kernel_width(rate, fps)  # a faster capture low-pass filtered first (.resample)
    local = resample_rotations(local, frames, width)
    root = resample_linear(root, frames, width)
    if ground:
        root = ground_align(local, root)
    return Motion(
        local,
        root,
        fps,
        source=str(path),
        source_skeleton=AMASS_WIDTHS[poses.shape[1]],
        check_rotations=False,
    )  # from axis-angles: rotations by construction


def save_amass(motion: Motion, path: str | Path, width: int = 156) -> None:
    """Write an AMASS-style npz (Z up) of a canonical motion; extra joints are zero."""
    if width not in AMASS_WIDTHS:
        raise ValueError(f"width must be one of {sorted(AMASS_WIDTHS)}")
    local = motion.local_rotations.astype(np.float64).copy()
    local[:, 0] = Z_UP_TO_Y_UP.T @ local[:, 0]
    poses = np.zeros((motion.num_frames, width))
    poses[:, : NUM_JOINTS * 3] = matrix_to_axis_angle(local).reshape(motion.num_frames, -1)
    trans = motion.root_translation.astype(np.float64) @ Z_UP_TO_Y_UP
    require_suffix(path, (".npz",), "an AMASS-style motion")
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:  # a handle: numpy appends .npz to a name
        np.savez(
            fh, poses=poses, trans=trans, mocap_framerate=np.float64(motion.fps), gender=np.str_("neutral")
        )
