"""What the add-on reads from our files without Blender: a GLB's timeline (the scene extras
hrr-export writes) and a PC2's header. Standard library only: it runs in Blender's Python."""

from __future__ import annotations

import json
import struct

GLB_MAGIC, JSON_CHUNK = 0x46546C67, 0x4E4F534A
PC2_HEADER = struct.Struct("<12siiffi")


def glb_timeline(path: str) -> tuple[float, int] | None:
    """(frames per second, frames) of a GLB written by hrr-export (its first scene's extras), or
    None for a GLB without them. A ValueError for a file that is not a GLB."""
    with open(path, "rb") as fh:
        header = fh.read(20)
        if len(header) < 20:
            raise ValueError(f"{path}: too short for a GLB")
        magic, _version, _length, chunk_length, chunk_type = struct.unpack("<5I", header)
        if magic != GLB_MAGIC or chunk_type != JSON_CHUNK:
            raise ValueError(f"{path}: not a GLB (binary glTF) file")
        document = json.loads(fh.read(chunk_length))
    scenes = document.get("scenes") or [{}]
    extras = scenes[document.get("scene", 0) or 0].get("extras") or {}
    fps, frames = extras.get("fps"), extras.get("frames")
    if not isinstance(fps, (int, float)) or not isinstance(frames, int) or not fps > 0 or frames < 1:
        return None
    return float(fps), frames


def pc2_frames(path: str) -> int:
    """The number of samples in a PC2 point cache; a ValueError for a file that is not one."""
    with open(path, "rb") as fh:
        header = fh.read(PC2_HEADER.size)
    if len(header) < PC2_HEADER.size:
        raise ValueError(f"{path}: too short for a PC2 point cache")
    magic, version, _points, _start, _rate, samples = PC2_HEADER.unpack(header)
    if magic != b"POINTCACHE2\0" or version != 1:
        raise ValueError(f"{path}: not a PC2 point cache")
    return samples
