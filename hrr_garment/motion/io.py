"""Loading any supported motion file as a canonical `Motion` at 30 fps, and saving motions.

Formats: BVH (retargeted by joint names: :mod:`.bvh_motion`), glTF / GLB animations of a skinned character
(:mod:`.gltf`, retargeted the same way), AMASS-style npz (SMPL / SMPL-H / SMPL-X pose widths, Z up), and the
project's native npz. Files are never unpickled.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from ..errors import MotionError
from ..io_utils import atomic_path, require_suffix
from .bvh_motion import PLAUSIBLE_HEIGHT_M, load_bvh
from .fbx import FBX_SUFFIX, load_fbx
from .gltf import GltfOptions, load_gltf
from .gltf_file import GLTF_SUFFIXES
from .joint_maps import load_joint_map
from .limits import (
    MAX_AXIS_ANGLE,
    MAX_SOURCE_FPS,
    MIN_SOURCE_FPS,
    ROTATION_TOLERANCE,
    check_frame_budget,
    check_root_speed,
    max_npz_bytes,
)
from .motion import FPS, MAX_TRANSLATION_M, Motion, check_local_rotations
from .resample import frame_chunks, resample_linear, resample_rotations, resample_times
from .retarget import ground_align
from .rotations import axis_angle_to_matrix, matrix_to_axis_angle
from .skeleton import JOINT_NAMES, NUM_JOINTS

NATIVE_FORMAT = "hrr_garment.motion"
NATIVE_VERSION = 1

# Z-up (AMASS) to Y-up: rotate -90 degrees about X, so +Z becomes +Y and +Y becomes -Z.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
AMASS_WIDTHS = {72: "smpl", 156: "smplh", 165: "smplx"}
NPZ_KINDS = "biufUS"  # dtype kinds an npz may hold: numbers and strings (bool only where it is read as such)


def load_motion(
    path: str | Path,
    unit_scale: float | None = None,
    joint_map: str | Path | dict | None = None,
    ground: bool = True,
    fps: float = FPS,
    source_fps: float | None = None,
    animation: str | int | None = None,
) -> Motion:
    """Load a BVH, FBX (through Blender: :mod:`.fbx`), glTF / GLB, AMASS-style npz or native npz
    file as a canonical motion at ``fps``.

    ``source_fps`` is the file's own frame rate, for files that carry none (or a wrong one): it
    replaces a BVH's frame time and an npz's rate key (glTF keys are in seconds: it does not apply).
    ``animation``: which of a glTF file's animations, by name or index (default the first).
    """
    path = Path(path)
    if not path.exists():
        raise MotionError(path, "file not found")
    if source_fps is not None:
        source_fps = check_source_fps(source_fps, path)
    suffix = path.suffix.lower()
    by_name = suffix in (".bvh", FBX_SUFFIX, *GLTF_SUFFIXES)  # the formats whose joints are matched by name
    custom = load_joint_map(joint_map) if by_name and isinstance(joint_map, (str, Path)) else joint_map
    if animation is not None and suffix not in GLTF_SUFFIXES:
        raise MotionError(
            path,
            f"only glTF / GLB files hold named animations; a {suffix or 'suffix-less'} file has one motion",
        )
    if suffix == ".bvh":
        motion = load_bvh(
            path, unit_scale=unit_scale, joint_map=custom, ground=ground, fps=fps, source_fps=source_fps
        )
    elif suffix in (*GLTF_SUFFIXES, FBX_SUFFIX):
        options = GltfOptions(animation=animation, unit_scale=unit_scale, joint_map=custom, fps=fps)
        motion = (load_fbx if suffix == FBX_SUFFIX else load_gltf)(path, options, ground=ground)
    elif suffix == ".npz":
        data = _read_npz(path)
        if "format" in data and str(data["format"]) == NATIVE_FORMAT:
            motion = _native_from_arrays(data, path)
            if source_fps is not None:
                motion.fps = source_fps
            motion = resample_motion(motion, fps, path)
        else:
            motion = load_amass(path, data, ground=ground, fps=fps, source_fps=source_fps)
    else:
        raise MotionError(
            path, f"unsupported motion file type {suffix!r} (expected .bvh, .fbx, .glb, .gltf or .npz)"
        )
    # what every format must give, whatever its values: a finite motion whose root does not teleport
    _check_finite(path, motion.local_rotations, motion.root_translation)
    check_root_speed(path, motion.root_translation, motion.fps)
    return motion


def check_source_fps(value: float, path: str | Path) -> float:
    """A file's frame rate as given by the user: finite, positive and plausible, or a clear error."""
    arr = np.asarray(value)
    if arr.size != 1 or arr.dtype.kind not in "iuf":
        raise MotionError(path, f"frame rate must be one real number, got {str(value)[:40]!r}")
    rate = float(arr.item())
    if not (np.isfinite(rate) and MIN_SOURCE_FPS <= rate <= MAX_SOURCE_FPS):
        raise MotionError(
            path,
            f"frame rate must be a finite number of frames per second in [{MIN_SOURCE_FPS:g}, "
            f"{MAX_SOURCE_FPS:g}], got {rate:g}",
        )
    return rate


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of an npz, after checking each one's declared size and dtype from its header:
    numbers and strings only (never objects), and at most ``max_npz_bytes()`` in all, so a huge
    declared shape or a compression bomb is refused before it is allocated."""
    limit, total, arrays = max_npz_bytes(), 0, {}
    try:
        with zipfile.ZipFile(path) as archive:
            for member in archive.infolist():
                name = member.filename[:-4] if member.filename.endswith(".npy") else member.filename
                with archive.open(member) as fh:
                    version = np.lib.format.read_magic(fh)
                    read_header = (
                        np.lib.format.read_array_header_1_0
                        if version == (1, 0)
                        else np.lib.format.read_array_header_2_0
                    )
                    shape, _, dtype = read_header(fh)
                if dtype.hasobject or dtype.kind not in NPZ_KINDS:
                    raise MotionError(
                        path, f"array {name!r} has dtype {dtype}; motion files hold numbers and strings only"
                    )
                total += max(int(np.prod(shape, dtype=np.float64)) * dtype.itemsize, member.file_size)
                if total > limit:
                    raise MotionError(
                        path,
                        f"its arrays take over {limit:,} bytes uncompressed (array {name!r} has shape "
                        f"{shape}); set HRR_MAX_NPZ_BYTES to raise the limit",
                    )
            with np.load(path, allow_pickle=False) as npz:
                arrays = {k: npz[k] for k in npz.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, KeyError) as exc:
        raise MotionError(path, f"not a readable npz file ({exc})") from None
    return arrays


def _numeric(
    path: Path, data: dict[str, np.ndarray], key: str, bound: float, dtype: type = np.float64
) -> np.ndarray:
    """``data[key]`` as ``dtype``: real numbers (not bool, complex, dates or text), finite and within
    +-``bound``."""
    values = data[key]
    if values.dtype.kind not in "iuf":
        raise MotionError(path, f"{key} has dtype {values.dtype}; expected real numbers")
    values = values.astype(dtype, copy=False)
    if values.size and values.ndim:
        _check_finite(path, values)
    if values.size and not (np.abs(values) <= bound).all():
        frame = (
            int(np.argmax(~(np.abs(values.reshape(len(values), -1)) <= bound).all(1))) if values.ndim else 0
        )
        raise MotionError(
            path,
            f"{key} has a value beyond +-{bound:g} (first at frame {frame}): a wrong unit or a corrupt file",
        )
    return values


def resample_motion(motion: Motion, fps: float = FPS, path: str | Path | None = None) -> Motion:
    """The motion at ``fps`` (rotations slerped, translations interpolated)."""
    if abs(motion.fps - fps) < 1e-6:
        return motion
    check_frame_budget(path or motion.source, motion.num_frames, motion.fps, fps_out=fps)
    frames = resample_times(motion.num_frames, motion.fps, fps)
    return Motion(
        resample_rotations(motion.local_rotations.astype(np.float64), frames),
        resample_linear(motion.root_translation.astype(np.float64), frames),
        fps,
        source=motion.source,
        source_skeleton=motion.source_skeleton,
        source_height_m=motion.source_height_m,
        check_rotations=False,  # slerped rotations
    )


# --- AMASS -----------------------------------------------------------------------------------------


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
            f"missing keys {missing} (AMASS-style npz needs poses, trans and the frame rate; native npz files carry format={NATIVE_FORMAT!r})",
        )
    if rate_key is None and source_fps is None:
        raise MotionError(
            path,
            "no frame rate: the file has no mocap_framerate (or mocap_frame_rate) key; "
            "give the rate it was captured at with --fps (e.g. --fps 120)",
        )
    poses = _numeric(path, data, "poses", MAX_AXIS_ANGLE)
    trans = _numeric(path, data, "trans", MAX_TRANSLATION_M)
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
    local = resample_rotations(local, frames)
    root = resample_linear(root, frames)
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


def _check_finite(path: Path, *arrays: np.ndarray) -> None:
    for a in arrays:
        ok = np.isfinite(a.reshape(a.shape[0], -1)).all(1)
        if not ok.all():
            raise MotionError(
                path,
                f"non-finite values (NaN or inf) in {int((~ok).sum())} frame(s), first at frame {int(np.argmin(ok))}",
            )


# --- native ----------------------------------------------------------------------------------------


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


def _native_from_arrays(data: dict[str, np.ndarray], path: Path) -> Motion:
    version = data.get("version", np.int64(-1))
    if version.dtype.kind not in "iu" or version.size != 1 or int(version) != NATIVE_VERSION:
        raise MotionError(
            path,
            f"native motion format version {str(version)[:20]} is not supported (this build reads version {NATIVE_VERSION})",
        )
    missing = [k for k in ("local_rotations", "root_translation", "fps") if k not in data]
    if missing:
        raise MotionError(path, f"missing keys {missing}")
    # float32, the precision a Motion keeps: hours of frames in float64 would be gigabytes
    rot = _numeric(path, data, "local_rotations", 1.0 + ROTATION_TOLERANCE, np.float32)
    if rot.ndim != 4 or rot.shape[1:] != (NUM_JOINTS, 3, 3):
        raise MotionError(path, f"local_rotations has shape {rot.shape}; expected (T, {NUM_JOINTS}, 3, 3)")
    if rot.shape[0] == 0:
        raise MotionError(path, "the motion has no frames")
    check_local_rotations(rot, JOINT_NAMES, path)  # named after the file, not the clip's stored name
    root = _numeric(path, data, "root_translation", MAX_TRANSLATION_M)
    if root.shape != (rot.shape[0], 3):
        raise MotionError(path, f"root_translation has shape {root.shape}; expected ({rot.shape[0]}, 3)")
    fps = check_source_fps(data["fps"], path)
    height = (
        float(_numeric(path, data, "source_height_m", PLAUSIBLE_HEIGHT_M[1] * 2))
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
