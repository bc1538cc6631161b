"""What a stage that adds a part to a trained bundle starts from (the baseline, the fast decoder):
the bundle and its dataset, checked to belong together."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from ..artifacts.bundle import Bundle
from ..artifacts.bundle_loader import load_bundle
from ..artifacts.bundle_writer import add_bundle_part
from ..artifacts.manifest_entries import PartEntry
from ..data.dataset import DatasetError, GarmentDataset
from ..data.windows import dataset_features
from ..io_utils import atomic_write_text, strict_json
from .report import StageReport


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


def frames_pve_mm(frames: np.ndarray, truth: np.ndarray) -> float:
    """Per-vertex error (mm): the mean distance between ``frames`` and ``truth`` (n, V, 3), metres."""
    return 1000.0 * float(np.linalg.norm(frames - truth, axis=-1).mean())


def decoded_pve_mm(bundle: Bundle, latents: list[np.ndarray], truth: np.ndarray) -> float:
    """Per-vertex error (mm, body frame) of standardised latents (:func:`decoded_frames`) against
    ``truth`` (sum of T, V, 3)."""
    return frames_pve_mm(decoded_frames(bundle, latents), truth)


@dataclass
class PartInputs:
    """What a stage that adds a trained part to a bundle starts from (:func:`part_inputs`)."""

    bundle: Bundle
    dataset: GarmentDataset
    key: str  # the part's key (:func:`part_key`)
    names: dict[str, list[str]]  # the dataset's train and val sequences
    latents: dict[str, np.ndarray]  # the autoencoder's latents of every sequence (T, nodes, C)
    features: dict[str, np.ndarray]  # the train and val sequences' motion features, as the code space's


def part_inputs(
    folder: Path, dataset: str | Path, cache_dir: Path | None, *, part: str, config, train
) -> tuple[PartInputs, dict | None]:
    """The inputs of the part ``part`` (its weights ``part``.safetensors) of settings ``config``
    trained with ``train`` (a dataclass; its time cap is not part of the key) on the bundle in
    ``folder``, and its bundle.json entry where one with the same key is there already (the stage
    is then reused: the inputs' latents and features are left empty)."""
    settings = [config.to_dict(), asdict(train) | {"max_minutes": None}]
    bundle, ds = bundle_and_dataset(folder, dataset, cache_dir)
    key = part_key(bundle, f"{part}.safetensors", settings, splits=ds.splits)
    names = {k: ds.splits[k] for k in ("train", "val")}
    recorded = getattr(bundle.manifest, part)
    if recorded is not None and recorded.key == key:
        return PartInputs(bundle, ds, key, names, {}, {}), {**recorded.to_dict(), "reused": True}
    with np.load(folder / "autoencoder" / "latents.npz", allow_pickle=False) as f:
        latents = {name: f[name] for name in ds.names}
    features = dataset_features(ds, names["train"] + names["val"], bundle.codespace.config)
    return PartInputs(bundle, ds, key, names, latents, features), None


def add_trained_part(folder: Path, part: str, model: torch.nn.Module, *, entry: dict) -> StageReport:
    """The trained ``model`` into the bundle as ``part``.safetensors with its bundle.json entry
    ``entry`` (and ``part``/report.json); the stage's report."""
    add_bundle_part(
        folder, f"{part}.safetensors", model.state_dict(), **{part: PartEntry.from_report(entry, part)}
    )
    atomic_write_text(folder / part / "report.json", strict_json(entry, indent=2))
    return part_report(part, folder, entry)


def part_report(part: str, folder: Path, entry: dict) -> StageReport:
    """The stage report of part ``part`` from its entry (``reused`` where the entry says so)."""
    return StageReport.of_record(part, folder / part, entry, reused=bool(entry.get("reused")))
