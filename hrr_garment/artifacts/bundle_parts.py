"""Loading a bundle's parts, each checked against what bundle.json and the configuration say
(:func:`~.bundle_loader.load_bundle` assembles them): network weights, array files, the fold store and the
fast decoder. Every problem is a :class:`~.manifest.BundleError` that names the file and what is off."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from safetensors import SafetensorError
from safetensors.numpy import load_file as load_arrays_file
from safetensors.torch import load_file as load_tensors

from ..garment.mesh import GarmentMesh
from ..models.subspace import SubspaceDecoder, SubspaceSettings
from .database import CodeDatabase
from .folds import FILE_KEYS as FOLD_FILE_KEYS
from .folds import FoldStore
from .manifest import FOLDS_FILE, SUBSPACE_FILE, BundleError
from .manifest_entries import FoldsEntry, SubspaceEntry
from .manifest_section import thawed


def load_state(module: torch.nn.Module, path: Path, folder: Path) -> None:
    """``module``'s weights from the safetensors file ``path``: every tensor present, of its shape, finite."""
    try:
        state = load_tensors(str(path))
    except (SafetensorError, OSError) as exc:
        raise BundleError(folder, f"{path.name} is unreadable ({exc})") from None
    expected = module.state_dict()
    missing, extra = sorted(set(expected) - set(state)), sorted(set(state) - set(expected))
    if missing or extra:
        raise BundleError(
            folder,
            f"{path.name} does not fit the configured network "
            f"(missing {missing[:3]}, unexpected {extra[:3]})",
        )
    for key, value in state.items():
        if tuple(value.shape) != tuple(expected[key].shape):
            raise BundleError(
                folder,
                f"{path.name}: {key} has shape {tuple(value.shape)}, the configuration needs "
                f"{tuple(expected[key].shape)}",
            )
    bad = [
        key for key, value in state.items() if value.is_floating_point() and not torch.isfinite(value).all()
    ]
    if bad:
        raise BundleError(folder, f"{path.name}: non-finite weights in {bad[:3]}")
    # Weight decay leaves some never-used weights (e.g. attention projections) at denormal
    # magnitudes (< 1.2e-38); CPUs take a slow path for each product with one, which doubled the
    # motion encoder's time on a trained model. As weights they are zeros.
    module.load_state_dict({key: flush_denormal_weights(value) for key, value in state.items()})


def flush_denormal_weights(t: torch.Tensor) -> torch.Tensor:
    """``t`` with its denormal floats (never-used weights decayed below 1.2e-38) set to zero."""
    if not t.is_floating_point():
        return t
    return torch.where(t.abs() < torch.finfo(t.dtype).tiny, torch.zeros((), dtype=t.dtype), t)


def load_arrays(folder: Path, name: str, keys: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The arrays of the bundle file ``name``: readable, holding ``keys``, finite where floating."""
    try:
        arrays = load_arrays_file(str(folder / name))
    except (SafetensorError, OSError) as exc:
        raise BundleError(folder, f"{name} is unreadable ({exc})") from None
    missing = [k for k in keys if k not in arrays]
    if missing:
        raise BundleError(folder, f"{name} lacks {missing}")
    bad = [k for k, v in arrays.items() if np.issubdtype(v.dtype, np.floating) and not np.isfinite(v).all()]
    if bad:
        raise BundleError(folder, f"{name}: non-finite values in {bad[:3]}")
    return arrays


def load_subspace(
    folder: Path, entry: SubspaceEntry, latent_shape: tuple, num_vertices: int
) -> SubspaceDecoder:
    """The fast decoder, its size and settings from bundle.json's ``subspace`` entry."""
    try:
        model = SubspaceDecoder(
            latent_shape,
            num_vertices,
            int(entry.components),
            config=SubspaceSettings.from_dict(thawed(entry.config)),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise BundleError(folder, f"bundle.json has a bad 'subspace' entry ({exc})") from None
    load_state(model, folder / SUBSPACE_FILE, folder)
    return model.eval()


def load_folds(folder: Path, entry: FoldsEntry, template: GarmentMesh, database: CodeDatabase) -> FoldStore:
    """The fold store, checked against the template and every database window it must cover."""
    levels = FOLD_FILE_KEYS["levels"]
    f = load_arrays(folder, FOLDS_FILE, (levels, "scale", "offsets"))
    try:
        folds = FoldStore(
            f[levels],
            f["scale"],
            f["offsets"],
            passes=entry.passes,
            encoding=entry.encoding,
            vertices=entry.vertices,
        )
        folds.check_fits(
            template.num_vertices,
            len(database.names),
            database.sequence,
            database.start + database.latents.shape[1],
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise BundleError(folder, f"{FOLDS_FILE}: {exc}") from None
    return folds
