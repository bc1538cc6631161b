"""Loading any supported motion file as a canonical `Motion` at 30 fps, and saving motions.

Formats: BVH (retargeted by joint names: :mod:`.bvh_motion`), glTF / GLB animations of a skinned
character (:mod:`.gltf`, retargeted the same way), AMASS-style npz (SMPL / SMPL-H / SMPL-X pose
widths, Z up: :mod:`.amass`), and the project's native npz (:mod:`.native_file`). Files are never
unpickled (:mod:`.npz_read`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import MotionError
from .amass import load_amass, save_amass  # noqa: F401  (save_amass: public, hrr_garment.save_amass)
from .bvh_motion import bvh_reading, load_bvh
from .fbx import FBX_SUFFIX, load_fbx
from .gltf import GltfSettings, load_gltf
from .gltf_file import GLTF_SUFFIXES
from .joint_maps import load_joint_map
from .limits import check_frame_budget, check_root_speed, check_source_fps
from .motion import FPS, Motion
from .native_file import NATIVE_FORMAT, native_from_arrays, save_motion  # noqa: F401  (save_motion: public)
from .npz_read import check_finite, read_npz
from .resample import kernel_width, resample_linear, resample_rotations, resample_times


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
        options = GltfSettings(animation=animation, unit_scale=unit_scale, joint_map=custom, fps=fps)
        motion = (load_fbx if suffix == FBX_SUFFIX else load_gltf)(path, options, ground=ground)
    elif suffix == ".npz":
        data = read_npz(path)
        if "format" in data and str(data["format"]) == NATIVE_FORMAT:
            motion = native_from_arrays(data, path)
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
    check_finite(path, motion.local_rotations, motion.root_translation)
    check_root_speed(path, motion.root_translation, motion.fps)
    return motion


def resample_motion(motion: Motion, fps: float = FPS, path: str | Path | None = None) -> Motion:
    """The motion at ``fps`` (rotations slerped, translations interpolated; from a rate
    :data:`~.resample.ANTI_ALIAS_RATIO` times faster or more, low-pass filtered: :mod:`.resample`)."""
    if abs(motion.fps - fps) < 1e-6:
        return motion
    check_frame_budget(path or motion.source, motion.num_frames, motion.fps, fps_out=fps)
    frames = resample_times(motion.num_frames, motion.fps, fps)
    width = kernel_width(motion.fps, fps)  # a faster motion low-pass filtered first (.resample)
    return Motion(
        resample_rotations(motion.local_rotations.astype(np.float64), frames, width),
        resample_linear(motion.root_translation.astype(np.float64), frames, width),
        fps,
        source=motion.source,
        source_skeleton=motion.source_skeleton,
        source_height_m=motion.source_height_m,
        check_rotations=False,  # slerped rotations
    )


def native_frame_rate(path: str | Path) -> float | None:
    """The frame rate a BVH or npz motion file was recorded at (a BVH's frame time, an npz's rate
    key); None for other formats or where the file does not say."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return bvh_reading(str(path), None, path.stat().st_mtime_ns)[0]
    if suffix == ".npz":
        data = read_npz(path)
        for key in ("fps", "mocap_framerate", "mocap_frame_rate"):
            if key in data and np.ndim(data[key]) == 0:
                return float(data[key])
    return None
