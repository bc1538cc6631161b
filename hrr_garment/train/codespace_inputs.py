"""What the code-space stage reads: the dataset's splits and training bodies, the autoencoder
stage's outputs (config, weights, latents) and the training and validation windows."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from ..body.body_file import body_to_dict
from ..body.mannequin import MANNEQUIN
from ..body.measures import BodyRange, body_vector
from ..data.dataset import DatasetError, GarmentDataset
from ..data.windows import build_windows, fit_stats, split_windows
from ..garment.fabrics import FABRICS
from ..garment.material_range import MaterialRange, material_vector
from ..models.codespace import CodeSpaceSettings
from .codespace_settings import PAPER_VALIDATION_FRACTION, CodeSpaceTrainSettings


def check_splits(ds: GarmentDataset) -> None:
    """The code space needs training and validation sequences."""
    if not ds.splits.get("train") or not ds.splits.get("val"):
        raise DatasetError(
            ds.path,
            f"needs at least one training and one validation sequence; it has "
            f"{len(ds.splits.get('train', []))} and {len(ds.splits.get('val', []))} "
            f"({len(ds.names)} sequences in all: simulate at least 3)",
        )


def training_bodies(ds: GarmentDataset) -> dict | None:
    """bundle.json's ``bodies`` of a model trained on ``ds``: the range of the bodies its training
    split was simulated on (:class:`~hrr_garment.body.measures.BodyRange`), the body it animates
    when given none (the one body of a model trained on one, the mannequin otherwise) and the body
    its garment was modelled on (``hrr-simulate --made-for``; None: the mannequin). None where the
    data is the mannequin's alone, as before bodies."""
    names = sorted({ds.body_name_of[n] for n in ds.splits["train"]})
    made_for = ds.info.get("made_for")
    if names == [MANNEQUIN] and ds.bodies[MANNEQUIN].is_mannequin and made_for is None:
        return None
    known = BodyRange.of([body_vector(ds.bodies[n].record) for n in names])
    return {
        "range": known.to_dict(),
        "default": body_to_dict(ds.bodies[names[0]].record) if len(names) == 1 else None,
        "made_for": made_for,
    }


def training_materials(ds: GarmentDataset) -> dict:
    """bundle.json's ``materials`` of a model trained on ``ds``: the range of the cloths its
    training split was simulated in (:class:`~hrr_garment.garment.material_range.MaterialRange`)
    and the cloth it animates when given none: the project's default cloth where the range holds
    it, else the training cloth nearest the range's middle (a model of one cloth: that cloth)."""
    cloths = {m.describe(): m for m in (ds.material_of(n) for n in ds.splits["train"])}
    vectors = {k: material_vector(m) for k, m in cloths.items()}
    known = MaterialRange.of(list(vectors.values()))
    default = FABRICS["default"]
    if known.outside(material_vector(default), margin=0.0):
        middle = (np.array(known.low) + np.array(known.high)) / 2
        spans = np.maximum(np.array(known.high) - np.array(known.low), 1e-9)
        nearest = min(sorted(vectors), key=lambda k: float((((vectors[k] - middle) / spans) ** 2).sum()))
        default = cloths[nearest]
    return {"range": known.to_dict(), "default": default.to_dict()}


def autoencoder_outputs(
    ds: GarmentDataset, dataset, ae_folder: Path
) -> tuple[dict, dict, dict[str, np.ndarray]]:
    """The autoencoder stage's config.json, weights and per-sequence latents, checked against the dataset."""
    if not (ae_folder / "latents.npz").is_file():
        raise DatasetError(
            ae_folder, "no latents.npz: run the autoencoder stage first (hrr-train --stage autoencoder)"
        )
    ae_meta = json.loads((ae_folder / "config.json").read_text())
    if ae_meta.get("vertices") != ds.template.num_vertices or ae_meta.get("garment") != ds.garment:
        raise DatasetError(
            dataset,
            f"the autoencoder in {ae_folder} was trained on {ae_meta.get('garment')} with "
            f"{ae_meta.get('vertices')} vertices, the dataset is {ds.garment} with "
            f"{ds.template.num_vertices}",
        )
    ae_state = torch.load(ae_folder / "model.pt", map_location="cpu", weights_only=True)
    with np.load(ae_folder / "latents.npz", allow_pickle=False) as f:
        latents = {name: f[name] for name in ds.names}
    return ae_meta, ae_state, latents


def codespace_windows(
    features: dict,
    latents: dict,
    splits: dict,
    config: CodeSpaceSettings,
    train_config: CodeSpaceTrainSettings,
):
    """Training and validation windows, their statistics, and the windows calibration decodes
    (None: every window of the validation clips)."""
    if train_config.validation == "windows":
        # the paper's protocol: the windows of the training and validation clips split 9:1
        clips = splits["train"] + splits["val"]
        train_w, val_w = split_windows(
            build_windows(features, latents, clips, window=config.window),
            PAPER_VALIDATION_FRACTION,
            train_config.seed,
        )
        motion_stats, latent_stats = fit_stats(features, latents, clips)
        calibration = [(clips[i], int(s)) for i, s in zip(val_w.sequence, val_w.start)]
    else:  # windows of both splits, standardised with the training split's statistics
        train_w = build_windows(features, latents, splits["train"], window=config.window)
        val_w = build_windows(features, latents, splits["val"], window=config.window)
        motion_stats, latent_stats = fit_stats(features, latents, splits["train"])
        calibration = None
    return train_w, val_w, motion_stats, latent_stats, calibration
