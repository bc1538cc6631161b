"""What the add-on reads from our files without Blender: a GLB's timeline (the scene extras
hrr-export writes) and a PC2's header. Standard library only: it runs in Blender's Python."""

from __future__ import annotations

import json
import math
import os
import struct

GLB_MAGIC, JSON_CHUNK = 0x46546C67, 0x4E4F534A
PC2_HEADER = struct.Struct("<12siiffi")
MAX_JSON_BYTES = 256 << 20  # the package's own bound on a GLB's JSON chunk
MAX_FPS = 1000.0  # the package's bound on a clip's rate (motion/limits.py)
MAX_FRAMES = 1_048_574  # the last frame Blender's timeline holds


def checked_timeline(path: str, fps, frames) -> tuple[float, int]:
    """(fps, frames) when they are a clip's rate and length Blender's timeline can hold; a
    ValueError naming ``path`` and the value otherwise (inf, 0 or 10^12 frames would crash the
    scene's settings or freeze it). A whole float counts as a frame count (USD custom properties)."""
    if isinstance(frames, float) and frames.is_integer():
        frames = int(frames)
    if (
        isinstance(fps, bool)
        or not isinstance(fps, (int, float))
        or not (math.isfinite(fps) and 0 < fps <= MAX_FPS)
    ):
        raise ValueError(f"{path}: its frame rate {fps!r} is not a rate above 0 and at most {MAX_FPS:g}")
    if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= MAX_FRAMES:
        raise ValueError(f"{path}: its frame count {frames!r} is not a whole number from 1 to {MAX_FRAMES}")
    return float(fps), frames


def _object(value, path: str, what: str) -> dict:
    if not isinstance(value, dict):
        raise ValueError(f"{path}: its glTF {what} is not an object")
    return value


def glb_timeline(path: str) -> tuple[float, int] | None:
    """(frames per second, frames) of a GLB written by hrr-export (its scene's extras), or None for a
    GLB without them. A ValueError naming the file for a file that is not a GLB, a document out of
    shape, or a timeline Blender cannot hold (:func:`checked_timeline`)."""
    with open(path, "rb") as fh:
        header = fh.read(20)
        if len(header) < 20:
            raise ValueError(f"{path}: too short for a GLB")
        magic, _version, _length, chunk_length, chunk_type = struct.unpack("<5I", header)
        if magic != GLB_MAGIC or chunk_type != JSON_CHUNK:
            raise ValueError(f"{path}: not a GLB (binary glTF) file")
        if chunk_length > min(MAX_JSON_BYTES, os.fstat(fh.fileno()).st_size - 20):
            raise ValueError(f"{path}: its JSON chunk claims {chunk_length} bytes, more than the file holds")
        try:
            document = json.loads(fh.read(chunk_length))
        except RecursionError:
            raise ValueError(f"{path}: its JSON is nested too deep") from None
        except ValueError as exc:  # not JSON, or not UTF-8
            raise ValueError(f"{path}: its JSON chunk is damaged ({exc})") from None
    document = _object(document, path, "document")
    scenes = document.get("scenes") or [{}]
    index = document.get("scene", 0) or 0
    if not isinstance(scenes, list) or isinstance(index, bool) or not isinstance(index, int):
        raise ValueError(f"{path}: its glTF scenes are not a list with a whole-number scene")
    if not 0 <= index < len(scenes):
        raise ValueError(f"{path}: its glTF scene {index} is not one of its {len(scenes)} scenes")
    extras = _object(_object(scenes[index], path, "scene").get("extras") or {}, path, "scene extras")
    fps, frames = extras.get("fps"), extras.get("frames")
    if fps is None or frames is None:  # another tool's GLB: the scene's rate is kept
        return None
    return checked_timeline(path, fps, frames)


def pc2_frames(path: str) -> int:
    """The number of samples in a PC2 point cache; a ValueError naming the file for one that is not
    a PC2, or whose points and samples are not what its bytes hold (Blender's Mesh Cache would read
    past the end) or what a timeline can hold."""
    with open(path, "rb") as fh:
        header = fh.read(PC2_HEADER.size)
        size = os.fstat(fh.fileno()).st_size
    if len(header) < PC2_HEADER.size:
        raise ValueError(f"{path}: too short for a PC2 point cache")
    magic, version, points, _start, _rate, samples = PC2_HEADER.unpack(header)
    if magic != b"POINTCACHE2\0" or version != 1:
        raise ValueError(f"{path}: not a PC2 point cache")
    if points < 1 or samples < 1 or samples > MAX_FRAMES:
        raise ValueError(f"{path}: a PC2 of {points} points and {samples} samples is not an animation")
    if PC2_HEADER.size + 12 * points * samples != size:
        raise ValueError(
            f"{path}: its header says {points} points x {samples} samples, but it holds {size} bytes"
        )
    return samples
