"""What a stage that adds a part to a trained bundle starts from (the baseline, the fast decoder):
the bundle and its dataset, checked to belong together."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import torch

from ..artifacts.bundle import Bundle
from ..artifacts.bundle_loader import load_bundle
from ..data.dataset import DatasetError, GarmentDataset


def bundle_and_dataset(
    folder: Path, dataset: str | Path, cache_dir: Path | None
) -> tuple[Bundle, GarmentDataset]:
    """The bundle in ``folder`` (the code-space stage must have written it) and ``dataset``; a
    DatasetError where the dataset is not of the model's garment and template."""
    bundle = load_bundle(folder, cache_dir)
    ds = GarmentDataset(dataset)
    if ds.garment != bundle.garment or ds.template.num_vertices != bundle.template.num_vertices:
        raise DatasetError(
            dataset,
            f"is not the dataset of the model in {folder} ({bundle.garment}, "
            f"{bundle.template.num_vertices} vertices)",
        )
    return bundle, ds


def part_key(bundle: Bundle, part_file: str, settings: list, *, splits: dict) -> str:
    """The key of a part trained on ``bundle`` (``part_file`` its weights' file): the part's
    ``settings`` (a time cap left out: it does not change what a finished training gives), every
    other file of the bundle and the dataset's splits. A stage with the same key is reused."""
    base_files = {k: v for k, v in bundle.manifest.files.items() if k != part_file}
    return hashlib.sha1(json.dumps([*settings, base_files, splits], sort_keys=True).encode()).hexdigest()[:16]


@torch.no_grad()
def decoded_frames(bundle: Bundle, latents: list[np.ndarray]) -> np.ndarray:
    """Standardised latents, ``latents`` (T, nodes x C) per sequence, decoded by the mesh decoder
    into body-frame vertices (sum of T, V, 3)."""
    decode = bundle.autoencoder.inference_decoder()
    shape = bundle.autoencoder.latent_shape
    return np.concatenate(
        [
            decode(
                torch.from_numpy(
                    bundle.latent_stats.denormalize(z).reshape(len(z), *shape).astype(np.float32)
                )
            ).numpy()
            for z in latents
        ]
    )


def decoded_pve_mm(bundle: Bundle, latents: list[np.ndarray], truth: np.ndarray) -> float:
    """Per-vertex error (mm, body frame) of standardised latents (:func:`decoded_frames`) against
    ``truth`` (sum of T, V, 3)."""
    return 1000.0 * float(np.linalg.norm(decoded_frames(bundle, latents) - truth, axis=-1).mean())
