"""BVH files as canonical motion: the rig's joints matched by name, its length unit detected from
its standing height, the clip resampled to 30 fps and retargeted (:mod:`.retarget`).
:func:`bvh_source` stops before retargeting: the clip on its own skeleton, in metres, which a
stream's rig (:mod:`.stream_rig`) calibrates on."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ..errors import MotionError
from .bvh import read_bvh
from .joint_maps import resolve_joint_map
from .limits import MAX_SOURCE_FPS, check_frame_budget
from .motion import FPS, Motion
from .reference_frames import leading_reference_frames
from .resample import kernel_width, resample_linear, resample_rotations, resample_times
from .retarget import SourceMotion, check_source, retarget, standing_height_from_legs
from .skeleton import forward_kinematics, rest_positions
from .skeleton_doubts import doubts_sentence, skeleton_doubts, warn_doubts

# Known length units (metres per file unit), tried in this order when detecting from height.
UNIT_SCALES = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "cmu": 0.0254 / 0.45,
    "dm": 0.1,
    "ft": 0.3048,
}
PLAUSIBLE_HEIGHT_M = (1.2, 2.3)
GIVEN_HEIGHT_M = (0.3, 3.0)  # what a unit scale the user gives may make of a skeleton (body.json's range)


def check_unit_scale(path: Path, unit_scale: float, *, rest: np.ndarray, mapping: dict[str, int]) -> float:
    """A user's ``--unit-scale``: a positive number that stands the rest skeleton ``rest`` (file
    units) at a body's height, else a :class:`MotionError` naming the file and the option."""
    if not (np.isfinite(unit_scale) and unit_scale > 0):
        raise MotionError(
            path, f"unit scale must be a positive number of metres per file unit, got {unit_scale}"
        )
    height = standing_height_from_legs(rest, mapping) * unit_scale
    lo, hi = GIVEN_HEIGHT_M
    if not lo <= height <= hi:
        raise MotionError(
            path,
            f"--unit-scale {unit_scale:g} stands its skeleton {height:.3g} m tall, where a body is "
            f"{lo:g}-{hi:g} m: give metres per file unit (0.01 for centimetres)",
        )
    return float(unit_scale)


def detect_unit_scale(rest: np.ndarray, mapping: dict[str, int], path: Path) -> float:
    """Metres per file unit, from the standing height of the rest pose ``rest`` (file units)."""
    height_units = standing_height_from_legs(rest, mapping)
    lo, hi = PLAUSIBLE_HEIGHT_M
    fits = [
        (abs(np.log(height_units * s / 1.7)), s) for s in UNIT_SCALES.values() if lo <= height_units * s <= hi
    ]
    if not fits:
        raise MotionError(
            path,
            f"cannot detect the length unit: standing height is {height_units:.4g} file units, which is no "
            f"plausible human height in {', '.join(UNIT_SCALES)}; pass --unit-scale (metres per file unit)",
        )
    return min(fits)[1]


def load_bvh(
    path: Path,
    unit_scale: float | None = None,
    joint_map: dict | None = None,
    ground: bool = True,
    fps: float = FPS,
    source_fps: float | None = None,
) -> Motion:
    """A BVH file as canonical motion: retargeted, grounded and resampled."""
    src, scheme, mapping, _ = bvh_source(path, unit_scale, joint_map, fps, source_fps)
    local, root = retarget(src, mapping, ground=ground)
    return Motion(
        local,
        root,
        fps,
        source=str(path),
        source_skeleton=scheme,
        source_height_m=standing_height_from_legs(src.rest_positions, mapping),
    )


@functools.lru_cache(maxsize=1024)
def bvh_reading(path: str, source_fps: float | None = None, mtime_ns: int = 0) -> tuple[float, int]:
    """(the rate the BVH file at ``path`` is read at: ``source_fps``, else its frame time's; how many
    leading reference frames reading it drops): what a dataset part's key records of the file, read
    once (``mtime_ns``: the file's, so that an edited file is read again)."""
    del mtime_ns
    clip = read_bvh(Path(path))
    rate = source_fps or 1.0 / clip.frame_time
    _, mapping = resolve_joint_map(clip.names, path, None)
    scale = detect_unit_scale(rest_positions(clip.offsets, clip.parents), mapping, Path(path))
    return rate, leading_reference_frames(clip.local_rotations, clip.local_translations[:, 0] * scale, rate)


def bvh_source(
    path: Path,
    unit_scale: float | None = None,
    joint_map: dict | None = None,
    fps: float = FPS,
    source_fps: float | None = None,
) -> tuple[SourceMotion, str, dict[str, int], float]:
    """A BVH file on its own skeleton, in metres, resampled to ``fps``: (the motion, the naming
    scheme, canonical joint name -> source joint index, metres per file unit)."""
    clip = read_bvh(path)
    scheme, mapping = resolve_joint_map(clip.names, str(path), joint_map)
    rest = rest_positions(clip.offsets, clip.parents)
    doubts = skeleton_doubts(clip.names, clip.parents, rest=rest, mapping=mapping)
    if unit_scale is None:
        try:
            unit_scale = detect_unit_scale(rest, mapping, path)
        except MotionError as exc:  # legs measured on the wrong joints: say which
            raise MotionError(
                path, f"{exc.problem}; {doubts_sentence(doubts)}" if doubts else exc.problem
            ) from None
    else:
        unit_scale = check_unit_scale(path, unit_scale, rest=rest, mapping=mapping)
    src_fps = source_fps or 1.0 / clip.frame_time
    if source_fps is None and src_fps > MAX_SOURCE_FPS:  # its low-pass filter would span millions of frames
        raise MotionError(
            path,
            f"its frame time {clip.frame_time:g} s is {src_fps:g} frames/s, more than {MAX_SOURCE_FPS:g}: "
            "give the capture rate with --fps",
        )
    check_frame_budget(path, clip.num_frames, src_fps, fps_out=fps)
    # a conversion's T-pose before the motion is no part of it (.reference_frames)
    start = leading_reference_frames(
        clip.local_rotations, clip.local_translations[:, 0] * unit_scale, src_fps
    )
    frames = resample_times(clip.num_frames - start, src_fps, fps)
    width = kernel_width(src_fps, fps)  # a faster capture low-pass filtered first (.resample)
    local_rot = resample_rotations(clip.local_rotations[start:], frames, width)
    local_trans = resample_linear(clip.local_translations[start:], frames, width) * unit_scale
    # Non-root translations: position channels hold the joint's parent-relative position.
    g_rot, g_pos = forward_kinematics(local_rot, local_trans[:, 0], local_trans, parents=clip.parents)
    src = SourceMotion(
        clip.names,
        clip.parents,
        rest * unit_scale,
        global_rotations=g_rot,
        global_positions=g_pos,
        fps=src_fps,
        path=str(path),
    )
    check_source(src)
    warn_doubts(str(path), doubts)
    return src, scheme, mapping, unit_scale
