"""Resuming the code-space stage: its settings keys (the stage's and the main training's), the
finished stage a re-run reuses, and the residual mode added to a finished bundle that predates it."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..artifacts.bundle_loader import BundleError, load_bundle
from ..artifacts.manifest_entries import ResidualEntry
from ..artifacts.typed_manifest import Manifest, read_manifest, update_manifest
from ..data.dataset import GarmentDataset
from ..io_utils import atomic_write_text, strict_json
from ..models.codespace import CodeSpaceSettings
from .codespace_settings import CodeSpaceTrainSettings
from .residual_calibration import calibrate_residual
from .training_frames import body_frames

CONTACT_SETTINGS = (
    "contact_steps",
    "contact_weight",
    "contact_margin_m",
)  # the contact phase's: not the main training's key
# settings that leave the main training as it is (contact_body: the phase's too, in its key where it
# changes what the phase trains against, stage_keys)
NOT_TRAINING = (*CONTACT_SETTINGS, "contact_body", "target_mm")


def main_training_key(
    config: CodeSpaceSettings,
    train_config: CodeSpaceTrainSettings,
    ae_state: dict,
    latents: dict[str, np.ndarray],
    ds: GarmentDataset,
) -> str:
    """The main training's settings key (without the contact phase's): a checkpoint with it is resumed."""
    # the latents as well as the weights: a changed encoding (refine_steps ...) re-encodes the same
    # weights, and the code space trained on the old latents must not be reused
    ae_hash = hashlib.sha256(
        b"".join(
            [k.encode() + ae_state[k].numpy().tobytes() for k in sorted(ae_state)]
            + [n.encode() + latents[n].tobytes() for n in ds.names]
        )
    ).hexdigest()[:16]
    training = {k: v for k, v in asdict(train_config).items() if k not in NOT_TRAINING} | {
        "max_minutes": None
    }
    if (
        train_config.latent_loss == "standardised"
    ):  # as before the setting existed: finished stages stay reused
        training = {k: v for k, v in training.items() if k not in ("latent_loss", "vertex_ridge")}
    model = config.to_dict()  # a model of one cloth: its key as before cloths were read
    return hashlib.sha1(
        json.dumps([model, training, ae_hash, ds.splits], sort_keys=True).encode()
    ).hexdigest()[:16]


def stage_keys(
    config: CodeSpaceSettings,
    train_config: CodeSpaceTrainSettings,
    ae_state: dict,
    latents: dict[str, np.ndarray],
    ds: GarmentDataset,
) -> tuple[str, str]:
    """(the stage's key, the main training's key). The contact phase comes after the training and
    does not change it: its settings are left out of the training's key (a model trained without
    the phase resumes its finished training and only adds the phase) and, where it runs, added to
    the stage's (without it, the stage's key is the training's, as before the phase existed)."""
    training = main_training_key(config, train_config, ae_state, latents, ds)
    if train_config.contact_steps == 0:
        return training, training
    phase = {k: getattr(train_config, k) for k in CONTACT_SETTINGS}
    if train_config.contact_body == "visible" and any(b.visible is not None for b in ds.bodies.values()):
        # the phase trains against skins: a stage whose phase ran before against the capsules of
        # the same bodies is not reused (on the mannequin's capsules the key is as before)
        phase["contact_body"] = "visible"
    settings = json.dumps([training, phase], sort_keys=True)
    return hashlib.sha1(settings.encode()).hexdigest()[:16], training


def finished_stage(folder: Path, report_path: Path, key: str) -> tuple[dict, Manifest] | None:
    """The report and bundle.json of a finished stage with these settings whose bundle is intact,
    else None."""
    if not (report_path.is_file() and (folder / "bundle.json").is_file()):
        return None
    report = json.loads(report_path.read_text())
    if report.get("key") != key:
        return None
    try:
        return report, read_manifest(folder)
    except BundleError:  # a damaged bundle is rebuilt
        return None


def add_residual_mode(
    folder: Path,
    report_path: Path,
    report: dict,
    ds: GarmentDataset,
    features: dict,
    val_names: list[str],
    calibration: list | None,
    cache_dir: Path | None,
) -> dict:
    """Calibrate the residual mode of a finished bundle that predates it, on the windows its tau
    was calibrated on; recorded in bundle.json and the stage's report."""
    bundle = load_bundle(folder, cache_dir)
    if bundle.database.motion is None:  # no motion windows to regress the matches from
        return report
    residual = calibrate_residual(
        bundle,
        {n: features[n] for n in val_names},
        {n: body_frames(ds, [n]) for n in val_names},
        windows=calibration,
    )
    update_manifest(folder, residual=ResidualEntry.from_report(residual, "residual"))
    report = {**report, "residual": residual}
    atomic_write_text(report_path, strict_json(report, indent=2, default=float))
    return report
