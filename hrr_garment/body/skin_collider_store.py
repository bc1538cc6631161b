"""The visible body's collider kept in the workspace, so that a body's grid is built once, not once a
process: an anny body's takes 6-7 s of one core, which every ``hrr-animate`` on it would pay.

    collider = stored_skin_collider(skinned)        # built, or read from HRR_HOME/cache/skin_collider

A grid is stored under the hash of everything it is built from (the mesh, its faces, weights and
rest pose, the settings) and of this format's version, as an ``.npz`` of plain arrays (never
pickled), written atomically. A file that cannot be read back whole, or whose arrays do not fit
the body, is built again and replaced.
"""

from __future__ import annotations

import hashlib
import zipfile
from dataclasses import astuple
from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..io_utils import atomic_path
from ..paths import workspace
from .skin_collider import SkinCollider, SkinColliderSettings, skin_collider
from .skinned_body import SkinnedBody

STORE_FORMAT = 2  # raise when SkinCollider's arrays or their meaning change
ARRAYS = ("origin", "shape", "distance", "joints", "weights", "face_start", "face_list")


def collider_key(body: SkinnedBody, settings: SkinColliderSettings) -> str:
    """The hash a body's grid is stored under."""
    digest = hashlib.sha256(f"skin-collider {STORE_FORMAT} {astuple(settings)!r}".encode())
    for array in (body.vertices, body.faces, body.weights, body.rest_rotations, body.rest_positions):
        a = np.ascontiguousarray(array)
        digest.update(f"{a.dtype.str}{a.shape}".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()[:32]


def stored_skin_collider(
    body: SkinnedBody, settings: SkinColliderSettings | None = None, folder: Path | None = None
) -> SkinCollider:
    """:func:`~.skin_collider.skin_collider` of ``body``, read from ``folder`` (default the workspace's
    ``cache/skin_collider``) where it was built before, else built and stored there."""
    settings = settings or SkinColliderSettings()
    path = (folder or workspace() / "cache" / "skin_collider") / f"{collider_key(body, settings)}.npz"
    stored = _read(path, body, settings)
    if stored is not None:
        return stored
    collider = skin_collider(body, settings)
    try:
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, **{name: getattr(collider, name) for name in ARRAYS})
    except (OSError, OutputError):  # a read-only workspace: the grid is still this process's to use
        pass
    return collider


def _read(path: Path, body: SkinnedBody, settings: SkinColliderSettings) -> SkinCollider | None:
    """The grid stored at ``path``, or None where there is none or it does not fit ``body``."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in ARRAYS}
    except (OSError, KeyError, ValueError, zipfile.BadZipFile, EOFError):
        return None
    nodes = int(np.prod(arrays["shape"])) if arrays["shape"].shape == (3,) else -1
    fits = (
        arrays["origin"].shape == (3,)
        and arrays["distance"].shape == (nodes,)
        and arrays["joints"].shape == arrays["weights"].shape == (nodes, arrays["joints"].shape[-1])
        and arrays["face_start"].shape == (nodes + 1,)
        and len(arrays["face_list"]) == int(arrays["face_start"][-1])
        and (
            arrays["face_list"].size == 0
            or 0 <= arrays["face_list"].min() <= arrays["face_list"].max() < len(body.faces)
        )
        and (arrays["joints"].size == 0 or int(arrays["joints"].max()) < body.weights.shape[1])
    )
    return SkinCollider(body, settings=settings, **arrays) if fits else None
