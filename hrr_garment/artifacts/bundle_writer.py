"""Writing a model bundle (:mod:`.bundle`): every file atomically, ``bundle.json`` last.

A folder whose ``bundle.json`` is missing, or whose files do not match the hashes it lists, is not a
bundle (:func:`~.typed_manifest.read_manifest` refuses it), so an interrupted write never looks like a
model. bundle.json is written from its typed :class:`~.typed_manifest.Manifest`: checked as any
reader will check it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from safetensors.numpy import save_file as save_arrays
from safetensors.torch import save_file as save_tensors

from ..garment.mesh import GarmentMesh
from ..io_utils import atomic_path
from ..models.codespace import CodeSpace
from ..models.fcmae import MeshAutoencoder
from ..motion.features import FeatureStats
from .database import CodeDatabase
from .folds import FoldStore
from .gate_signals import check_gate_signal
from .manifest import FOLDS_FILE, FORMAT_VERSION, NETWORKS, content_hash, sha256
from .manifest_section import as_json
from .typed_manifest import parse_manifest, read_manifest, write_manifest


def _save(path: Path, tensors: dict, numpy: bool = False) -> None:
    with atomic_path(path) as tmp:
        if numpy:
            save_arrays({k: np.ascontiguousarray(v) for k, v in tensors.items()}, str(tmp))
        else:
            save_tensors({k: v.detach().contiguous() for k, v in tensors.items()}, str(tmp))


@dataclass(frozen=True)
class BundleParts:
    """What a bundle holds besides its manifest's settings: the trained networks, their
    statistics, the retrieval database, the template and the detail mode's folds (:mod:`.folds`)."""

    autoencoder: MeshAutoencoder
    codespace: CodeSpace
    motion_stats: FeatureStats
    latent_stats: FeatureStats
    database: CodeDatabase
    template: GarmentMesh
    folds: FoldStore | None = None


def write_bundle(
    folder: str | Path, parts: BundleParts, *, tau: float, info: dict, gate: str = "entropy"
) -> Path:
    """Write (or replace) the bundle in ``folder``; returns the path of ``bundle.json``. ``tau``:
    the threshold of the hybrid's ``gate`` signal; ``info``: more of bundle.json's fields."""
    check_gate_signal(gate)
    autoencoder, codespace, template, folds = parts.autoencoder, parts.codespace, parts.template, parts.folds
    motion_stats, latent_stats, database = parts.motion_stats, parts.latent_stats, parts.database
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "bundle.json").unlink(missing_ok=True)  # the old bundle stops being one first
    _save(folder / "autoencoder.safetensors", autoencoder.state_dict())
    for name in NETWORKS:
        _save(folder / f"{name}.safetensors", getattr(codespace, name).state_dict())
    _save(
        folder / "stats.safetensors",
        {
            "motion_mean": motion_stats.mean,
            "motion_std": motion_stats.std,
            "latent_mean": latent_stats.mean,
            "latent_std": latent_stats.std,
        },
        numpy=True,
    )
    _save(folder / "database.safetensors", database.arrays(), numpy=True)
    # the template's vertex groups too (``group/NAME``): evaluation measures the hem's swing
    _save(
        folder / "template.safetensors",
        {
            "vertices": template.vertices.astype(np.float32),
            "faces": template.faces.astype(np.int32),
            "attached": template.attached,
            **{f"group/{k}": np.asarray(v, np.int32) for k, v in template.groups.items() if k != "attached"},
        },
        numpy=True,
    )
    parts = [
        "autoencoder.safetensors",
        "stats.safetensors",
        "database.safetensors",
        "template.safetensors",
        *[f"{n}.safetensors" for n in NETWORKS],
    ]
    if folds is not None:
        _save(folder / FOLDS_FILE, folds.arrays(), numpy=True)
        parts.append(FOLDS_FILE)
        info = {**info, "folds": folds.entry.to_dict()}
    files = {p: sha256(folder / p) for p in sorted(parts)}
    meta = {
        "format_version": FORMAT_VERSION,
        "garment": template.name,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "autoencoder": {
            "config": autoencoder.config.to_dict(),
            "scale": float(autoencoder.scale),
            "sizes": list(autoencoder.hierarchy.sizes),
        },
        "codespace": {
            "config": codespace.config.to_dict(),
            "features": codespace.features,
            "latent_shape": list(codespace.latent_shape),
        },
        "tau": float(tau),
        "gate": gate,
        "gates": {},
        "database": {"names": database.names, "classes": database.classes, "windows": len(database)},
        "files": files,
        "content_hash": content_hash(files),
        **info,
    }
    return write_manifest(folder, parse_manifest(folder, as_json(meta)))


def add_bundle_part(
    folder: str | Path, name: str, tensors: dict, numpy: bool = False, **changes: Any
) -> None:
    """Add (or replace) one file of an existing bundle (torch tensors, or ``numpy`` arrays) and
    replace the manifest's fields ``changes`` (typed sections: ``subspace=PartEntry(...)``; None
    drops one); the file list and content hash are updated, bundle.json last (atomically)."""
    folder = Path(folder)
    current = read_manifest(folder)
    _save(folder / name, tensors, numpy)
    files = {**current.files, name: sha256(folder / name)}
    write_manifest(folder, replace(current, files=files, content_hash=content_hash(files), **changes))
