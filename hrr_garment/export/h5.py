"""``out.h5``: an animated garment as hrr-animate writes it (DESIGN 9).

    /faces                (F, 3) int32
    /vertices             (T, V, 3) float32, one frame per chunk, gzip + shuffle
    /body/joints          (T, 22, 3) float32
    /diagnostics/mode     (T,) uint8, 1 = retrieval, 0 = regression
    /diagnostics/entropy  (T,) float32, motion-code entropy (nats)
    /diagnostics/source   (T, 2) int32, retrieved (database sequence, frame) or -1
    attributes: fps, units ("m"), up_axis ("Y"), garment, source_motion, format_version,
                model_hash, mode, tau, plus any extra ones given

Written to a temporary file and renamed, so a failed run leaves no half file.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from ..io_utils import atomic_path

FORMAT_VERSION = 1


def write_animation_h5(path: str | Path, *, vertices: np.ndarray, faces: np.ndarray, joints: np.ndarray, mode: np.ndarray,
                       entropy: np.ndarray, source: np.ndarray, attrs: dict) -> Path:
    path = Path(path)
    t, v = vertices.shape[:2]
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.create_dataset("faces", data=np.asarray(faces, np.int32))
        f.create_dataset("vertices", data=np.asarray(vertices, np.float32), chunks=(1, v, 3), compression="gzip",
                         compression_opts=4, shuffle=True)
        f.create_dataset("body/joints", data=np.asarray(joints, np.float32))
        f.create_dataset("diagnostics/mode", data=np.asarray(mode, np.uint8))
        f.create_dataset("diagnostics/entropy", data=np.asarray(entropy, np.float32))
        f.create_dataset("diagnostics/source", data=np.asarray(source, np.int32).reshape(t, 2))
        f.attrs.update({"fps": 30.0, "units": "m", "up_axis": "Y", "format_version": FORMAT_VERSION})
        f.attrs.update({k: v for k, v in attrs.items() if v is not None})
    return path


def read_animation_h5(path: str | Path) -> dict:
    """Everything in an out.h5 as arrays plus ``attrs``."""
    with h5py.File(path, "r") as f:
        out = {k: f[k][()] for k in ("faces", "vertices", "body/joints", "diagnostics/mode", "diagnostics/entropy",
                                      "diagnostics/source")}
        out["attrs"] = dict(f.attrs)
    return out
