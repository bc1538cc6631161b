"""Loading any supported motion file as a canonical `Motion` at 30 fps, and saving motions.

Formats: BVH (retargeted by joint names), AMASS-style npz (SMPL / SMPL-H / SMPL-X pose widths,
Z up), and the project's native npz. Files are never unpickled.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from ..errors import MotionError
from ..io_utils import atomic_path
from .bvh import read_bvh
from .joint_maps import load_joint_map, resolve_joint_map
from .motion import FPS, Motion
from .resample import resample_linear, resample_rotations, resample_times
from .retarget import (
    SourceMotion,
    check_source,
    ground_align,
    retarget,
    standing_height_from_legs,
)
from .rotations import axis_angle_to_matrix, matrix_to_axis_angle
from .skeleton import NUM_JOINTS, forward_kinematics, rest_positions

NATIVE_FORMAT = "hrr_garment.motion"
NATIVE_VERSION = 1

# Known length units (metres per file unit), tried in this order when detecting from height.
UNIT_SCALES = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45, "dm": 0.1, "ft": 0.3048}
PLAUSIBLE_HEIGHT_M = (1.2, 2.3)

# Z-up (AMASS) to Y-up: rotate -90 degrees about X, so +Z becomes +Y and +Y becomes -Z.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
AMASS_WIDTHS = {72: "smpl", 156: "smplh", 165: "smplx"}


def load_motion(
    path: str | Path,
    unit_scale: float | None = None,
    joint_map: str | Path | dict | None = None,
    ground: bool = True,
    fps: float = FPS,
    source_fps: float | None = None,
) -> Motion:
    """Load a BVH, AMASS-style npz or native npz file as a canonical motion at ``fps``.

    ``source_fps`` is the file's own frame rate, for files that carry none (or a wrong one): it
    replaces a BVH's frame time and an npz's rate key.
    """
    path = Path(path)
    if not path.exists():
        raise MotionError(path, "file not found")
    if source_fps is not None:
        source_fps = check_source_fps(source_fps, path)
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        custom = load_joint_map(joint_map) if isinstance(joint_map, (str, Path)) else joint_map
        return load_bvh(path, unit_scale=unit_scale, joint_map=custom, ground=ground, fps=fps, source_fps=source_fps)
    if suffix == ".npz":
        data = _read_npz(path)
        if "format" in data and str(data["format"]) == NATIVE_FORMAT:
            motion = _native_from_arrays(data, path)
            if source_fps is not None:
                motion.fps = source_fps
            return resample_motion(motion, fps)
        return load_amass(path, data, ground=ground, fps=fps, source_fps=source_fps)
    raise MotionError(path, f"unsupported motion file type {suffix!r} (expected .bvh or .npz)")


MAX_SOURCE_FPS = 1000.0  # above this a "frame rate" is a unit mistake, not a capture rate


def check_source_fps(value: float, path: str | Path) -> float:
    """A file's frame rate as given by the user: finite, positive and plausible, or a clear error."""
    arr = np.asarray(value)
    if arr.size != 1 or arr.dtype.kind not in "iuf":
        raise MotionError(path, f"frame rate must be one real number, got {str(value)[:40]!r}")
    rate = float(arr.item())
    if not (np.isfinite(rate) and 0 < rate <= MAX_SOURCE_FPS):
        raise MotionError(path, f"frame rate must be a finite number of frames per second in (0, {MAX_SOURCE_FPS:g}], got {rate:g}")
    return rate


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as npz:
            return {k: npz[k] for k in npz.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise MotionError(path, f"not a readable npz file ({exc})") from None


def resample_motion(motion: Motion, fps: float = FPS) -> Motion:
    """The motion at ``fps`` (rotations slerped, translations interpolated)."""
    if abs(motion.fps - fps) < 1e-6:
        return motion
    frames = resample_times(motion.num_frames, motion.fps, fps)
    return Motion(
        resample_rotations(motion.local_rotations.astype(np.float64), frames),
        resample_linear(motion.root_translation.astype(np.float64), frames),
        fps, motion.source, motion.source_skeleton, motion.source_height_m,
    )


# --- BVH -------------------------------------------------------------------------------------------


def detect_unit_scale(rest: np.ndarray, mapping: dict[str, int], path: Path) -> float:
    """Metres per file unit, from the standing height of the rest pose ``rest`` (file units)."""
    height_units = standing_height_from_legs(rest, mapping)
    lo, hi = PLAUSIBLE_HEIGHT_M
    fits = [(abs(np.log(height_units * s / 1.7)), s) for s in UNIT_SCALES.values() if lo <= height_units * s <= hi]
    if not fits:
        raise MotionError(path, f"cannot detect the length unit: standing height is {height_units:.4g} file units, which is no plausible human height in {', '.join(UNIT_SCALES)}; pass --unit-scale (metres per file unit)")
    return min(fits)[1]


def load_bvh(path: Path, unit_scale: float | None = None, joint_map: dict | None = None, ground: bool = True, fps: float = FPS,
             source_fps: float | None = None) -> Motion:
    """A BVH file as canonical motion: retargeted, grounded and resampled."""
    clip = read_bvh(path)
    scheme, mapping = resolve_joint_map(clip.names, str(path), joint_map)
    rest = rest_positions(clip.offsets, clip.parents)
    if unit_scale is None:
        unit_scale = detect_unit_scale(rest, mapping, path)
    elif not unit_scale > 0:
        raise MotionError(path, f"unit scale must be positive, got {unit_scale}")
    src_fps = source_fps or 1.0 / clip.frame_time
    frames = resample_times(clip.num_frames, src_fps, fps)
    local_rot = resample_rotations(clip.local_rotations, frames)
    local_trans = resample_linear(clip.local_translations, frames) * unit_scale
    # Non-root translations: position channels hold the joint's parent-relative position.
    g_rot, g_pos = forward_kinematics(local_rot, local_trans[:, 0], local_trans, clip.parents)
    src = SourceMotion(clip.names, clip.parents, rest * unit_scale, g_rot, g_pos, src_fps, str(path))
    check_source(src)
    local, root = retarget(src, mapping, ground=ground)
    height = standing_height_from_legs(src.rest_positions, mapping)
    return Motion(local, root, fps, str(path), scheme, height)


# --- AMASS -----------------------------------------------------------------------------------------


def load_amass(path: Path, data: dict[str, np.ndarray], ground: bool = True, fps: float = FPS,
               source_fps: float | None = None) -> Motion:
    """AMASS-style npz: the first 22 joints of ``poses`` are SMPL body joints, Z up. ``poses`` is
    (T, 72|156|165) or per joint (T, 24|52|55, 3); ``source_fps`` stands in for a missing rate key."""
    missing = [k for k in ("poses", "trans") if k not in data]
    rate_key = next((k for k in ("mocap_framerate", "mocap_frame_rate") if k in data), None)
    if missing:
        raise MotionError(path, f"missing keys {missing} (AMASS-style npz needs poses, trans and the frame rate; native npz files carry format={NATIVE_FORMAT!r})")
    if rate_key is None and source_fps is None:
        raise MotionError(path, "no frame rate: the file has no mocap_framerate (or mocap_frame_rate) key; "
                                "give the rate it was captured at with --fps (e.g. --fps 120)")
    poses = np.asarray(data["poses"], dtype=np.float64)
    trans = np.asarray(data["trans"], dtype=np.float64)
    if poses.ndim == 3 and poses.shape[2] == 3 and poses.shape[1] * 3 in AMASS_WIDTHS:
        poses = poses.reshape(poses.shape[0], -1)  # per-joint axis-angle
    if poses.ndim != 2 or poses.shape[1] not in AMASS_WIDTHS:
        raise MotionError(path, f"poses has shape {poses.shape}; expected (T, 72|156|165) or (T, 24|52|55, 3) "
                                "for SMPL, SMPL-H or SMPL-X")
    if trans.shape != (poses.shape[0], 3):
        raise MotionError(path, f"trans has shape {trans.shape}; expected ({poses.shape[0]}, 3) to match poses")
    rate = source_fps if source_fps is not None else check_source_fps(data[rate_key], f"{path}: {rate_key}")
    _check_finite(path, poses, trans)
    if poses.shape[0] == 0:
        raise MotionError(path, "the motion has no frames")
    local = axis_angle_to_matrix(poses[:, : NUM_JOINTS * 3].reshape(-1, NUM_JOINTS, 3))
    local[:, 0] = Z_UP_TO_Y_UP @ local[:, 0]
    root = trans @ Z_UP_TO_Y_UP.T
    frames = resample_times(poses.shape[0], rate, fps)
    local = resample_rotations(local, frames)
    root = resample_linear(root, frames)
    if ground:
        root = ground_align(local, root)
    return Motion(local, root, fps, str(path), AMASS_WIDTHS[poses.shape[1]])


def save_amass(motion: Motion, path: str | Path, width: int = 156) -> None:
    """Write an AMASS-style npz (Z up) of a canonical motion; extra joints are zero."""
    if width not in AMASS_WIDTHS:
        raise ValueError(f"width must be one of {sorted(AMASS_WIDTHS)}")
    local = motion.local_rotations.astype(np.float64).copy()
    local[:, 0] = Z_UP_TO_Y_UP.T @ local[:, 0]
    poses = np.zeros((motion.num_frames, width))
    poses[:, : NUM_JOINTS * 3] = matrix_to_axis_angle(local).reshape(motion.num_frames, -1)
    trans = motion.root_translation.astype(np.float64) @ Z_UP_TO_Y_UP
    with atomic_path(path) as tmp:
        np.savez(tmp, poses=poses, trans=trans, mocap_framerate=np.float64(motion.fps), gender=np.str_("neutral"))


def _check_finite(path: Path, *arrays: np.ndarray) -> None:
    for a in arrays:
        ok = np.isfinite(a.reshape(a.shape[0], -1)).all(1)
        if not ok.all():
            raise MotionError(path, f"non-finite values (NaN or inf) in {int((~ok).sum())} frame(s), first at frame {int(np.argmin(ok))}")


# --- native ----------------------------------------------------------------------------------------


def save_motion(motion: Motion, path: str | Path) -> None:
    """The native npz: canonical local rotation matrices, root translation, fps, provenance (versioned)."""
    with atomic_path(path) as tmp:
        np.savez(
            tmp,
            format=np.str_(NATIVE_FORMAT),
            version=np.int64(NATIVE_VERSION),
            local_rotations=motion.local_rotations.astype(np.float32),
            root_translation=motion.root_translation.astype(np.float64),
            fps=np.float64(motion.fps),
            source=np.str_(motion.source),
            source_skeleton=np.str_(motion.source_skeleton),
            source_height_m=np.float64(motion.source_height_m),
        )


def _native_from_arrays(data: dict[str, np.ndarray], path: Path) -> Motion:
    version = int(data.get("version", -1))
    if version != NATIVE_VERSION:
        raise MotionError(path, f"native motion format version {version} is not supported (this build reads version {NATIVE_VERSION})")
    missing = [k for k in ("local_rotations", "root_translation", "fps") if k not in data]
    if missing:
        raise MotionError(path, f"missing keys {missing}")
    rot = data["local_rotations"]
    if rot.ndim != 4 or rot.shape[1:] != (NUM_JOINTS, 3, 3):
        raise MotionError(path, f"local_rotations has shape {rot.shape}; expected (T, {NUM_JOINTS}, 3, 3)")
    if data["root_translation"].shape != (rot.shape[0], 3):
        raise MotionError(path, f"root_translation has shape {data['root_translation'].shape}; expected ({rot.shape[0]}, 3)")
    _check_finite(path, rot, data["root_translation"])
    return Motion(rot, data["root_translation"], float(data["fps"]), str(data.get("source", path)), str(data.get("source_skeleton", "canonical")), float(data.get("source_height_m", 1.7)))
