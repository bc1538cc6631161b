"""Point caches: PC2 (Blender's Mesh Cache modifier, 3ds Max) with its base OBJ, and OBJ sequences.

PC2 layout (little endian): the 12 bytes ``POINTCACHE2\\0``, int32 version (1), int32 point count,
float32 start frame, float32 sample rate (frames per sample, 1 here), int32 sample count, then
float32 x, y, z per point per sample. Points are in out.h5's frame (Y up, metres) and in the OBJ's
vertex order, so the cache applies to the base OBJ as written (see docs/export.md for Blender's
axis settings).
"""

from __future__ import annotations

import os
import shutil
import struct
import tempfile
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..data.animation_file import AnimationFile
from ..errors import InputError
from ..garment.obj import SMOOTH_SHADING, format_rows, write_obj
from ..input_files import MAX_BINARY_BYTES, read_input
from ..io_utils import atomic_path, storage_error

_PC2_HEADER = struct.Struct("<12siiffi")
_PC2_MAGIC = b"POINTCACHE2\0"


def write_pc2(vertices: np.ndarray, path: str | Path, start_frame: float = 0.0) -> Path:
    """Write (T, V, 3) vertices as a PC2 file, atomically."""
    path = Path(path)
    t, v = vertices.shape[:2]
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(_PC2_HEADER.pack(_PC2_MAGIC, 1, v, float(start_frame), 1.0, t))
        fh.write(np.ascontiguousarray(vertices, "<f4").tobytes())
    return path


def read_pc2(path: str | Path) -> tuple[np.ndarray, float, float]:
    """(vertices (T, V, 3) float32, start frame, sample rate); checks the header against the size."""
    path = Path(path)
    data = read_input(path, limit=MAX_BINARY_BYTES, what="a PC2 file")
    if len(data) < _PC2_HEADER.size:
        raise InputError(path, "too short for a PC2 header")
    magic, version, points, start, rate, samples = _PC2_HEADER.unpack_from(data)
    if magic != _PC2_MAGIC or version != 1:
        raise InputError(path, f"not a PC2 file (magic {magic!r}, version {version})")
    expected = _PC2_HEADER.size + 12 * points * samples
    if len(data) != expected:
        raise InputError(
            path, f"{len(data)} bytes, but the header ({samples} samples of {points} points) needs {expected}"
        )
    return np.frombuffer(data, "<f4", offset=_PC2_HEADER.size).reshape(samples, points, 3), start, rate


def write_pc2_with_obj(anim: AnimationFile, path: str | Path) -> tuple[Path, Path]:
    """``path`` (.pc2) plus the base mesh (frame 0) beside it as the same name with .obj."""
    path = Path(path)
    write_pc2(anim.vertices, path)
    try:
        base = write_obj(path.with_suffix(".obj"), anim.vertices[0], anim.faces)
    except BaseException:
        path.unlink(missing_ok=True)  # a cache without its base mesh is of no use: leave neither
        raise
    return path, base


def write_obj_sequence(
    anim: AnimationFile, directory: str | Path, stem: str | None = None, progress: bool = True
) -> list[Path]:
    """One OBJ per frame, ``STEM_00000.obj`` ..., into ``directory``. The frames are written into a
    temporary folder beside it and moved in only when all are done, so a failed export leaves no
    partial sequence; the frames of an earlier export with the same stem are replaced (extra ones removed)."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise InputError(directory, "an OBJ sequence is written into a folder, and this is a file")
    stem = stem or str(anim.attrs.get("garment", "garment"))
    faces = SMOOTH_SHADING + "g garment\n" + format_rows("f %d %d %d", anim.faces + 1)
    names = [f"{stem}_{t:05d}.obj" for t in range(anim.num_frames)]
    try:
        directory.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{directory.name}.", dir=directory.parent))
    except OSError as exc:
        raise storage_error(directory, exc) from None
    try:
        for name, vertices in zip(tqdm(names, desc="obj", unit="frame", disable=not progress), anim.vertices):
            with open(staging / name, "w", encoding="utf-8") as fh:
                fh.write("# hrr_garment\n")
                fh.write(format_rows("v %.6f %.6f %.6f", vertices))
                fh.write(faces)
        directory.mkdir(exist_ok=True)
        for stale in set(p.name for p in directory.glob(f"{stem}_[0-9][0-9][0-9][0-9][0-9].obj")) - set(
            names
        ):
            (directory / stale).unlink()
        for name in names:
            os.replace(staging / name, directory / name)
    except OSError as exc:  # disk full or the folder made read-only meanwhile
        raise storage_error(directory, exc) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return [directory / n for n in names]
