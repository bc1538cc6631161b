"""The code-space stage of ``hrr-train``: windows -> code space -> database -> tau -> bundle.

Reads the dataset and the autoencoder stage's outputs (``MODEL/autoencoder/``: weights and
latents of every frame), trains the code space in ``MODEL/codebook/`` (checkpointed, resumable;
the folder keeps the stage's old name so that models trained before the rename resume), builds
the retrieval database from every training window's garment code, calibrates tau on the
validation split (the hybrid's gate and the residual mode's weight), and writes the bundle at the
top of ``MODEL/`` (:mod:`hrr_garment.artifacts.bundle`). A re-run with nothing changed finds the
finished report and returns it without redoing anything (a bundle from before the residual mode
or the detail mode's folds only has what it lacks added).

What the stage reads is in :mod:`~hrr_garment.train.codespace_inputs`, its keys and the reuse of
a finished stage in :mod:`~hrr_garment.train.codespace_resume`, the epoch in
:mod:`~hrr_garment.train.codespace_training` (its settings in
:mod:`~hrr_garment.train.codespace_settings`, its losses in :mod:`~hrr_garment.train.codespace_losses`).
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from ..artifacts.bundle_writer import BundleParts, add_bundle_part, write_bundle
from ..artifacts.database import CodeDatabase
from ..artifacts.folds import FOLD_ENCODING, FoldStore
from ..artifacts.manifest import FOLDS_FILE
from ..artifacts.manifest_entries import MaterialsEntry
from ..artifacts.manifest_section import thawed
from ..artifacts.typed_manifest import update_manifest
from ..body.measures import BODY_MEASURES
from ..data.dataset import GarmentDataset
from ..data.windows import dataset_features
from ..garment.material_range import MATERIAL_FEATURES
from ..garment.smoothing import mean_operator
from ..io_utils import atomic_write_text, strict_json
from ..models.codespace import CodeSpace, CodeSpaceSettings
from ..motion.licences import licences_of
from .autoencoder import load_autoencoder
from .autoencoder_settings import refine_settings
from .calibrate import window_mode_errors
from .codespace_inputs import (
    autoencoder_outputs,
    check_splits,
    codespace_windows,
    training_bodies,
    training_materials,
)
from .codespace_losses import WindowTensors, evaluate, mean_square
from .codespace_resume import add_residual_mode, finished_stage, stage_keys
from .codespace_settings import CodeSpaceTrainSettings
from .codespace_training import train_codespace
from .contact import BodyContacts, ContactWindows, FrameDecoder, teach_contact
from .report import StageReport
from .schedule import cap_since_raised
from .training_frames import body_frames
from .vertex_metric import VertexMetric, sample_frames

STAGE_FOLDER = "codebook"  # under MODEL/: the name from before "code space" was the stage's name


@torch.no_grad()
def garment_codes(model: CodeSpace, windows: WindowTensors, batch: int = 512) -> np.ndarray:
    """Argmax garment codes (N, G) uint8 of standardised latent windows."""
    model.eval()
    out = []
    for i in range(0, len(windows), batch):  # the latent windows, and the body of a model across bodies
        motion, latents = windows[slice(i, i + batch)]
        out.append(
            model.quantizer.split(model.garment_encoder(latents, model.condition_of(motion))).argmax(-1)
        )
    return torch.cat(out).numpy().astype(np.uint8)


def _stage_report(report: dict, folder: Path, reused: bool = False) -> StageReport:
    training = report["training"]
    return StageReport(
        "codespace",
        folder,
        int(training["epoch"]),
        best_epoch=int(training["best_epoch"]),
        minutes=float(report["minutes"]),
        reused=reused,
        metrics={**report, "reused": True} if reused else report,
        epochs_asked=training.get("config", {}).get("epochs"),
        stopped=training.get("stopped"),
        validation_mm=report.get("validation_mm", {}).get("regression"),
    )


def fold_store(ds: GarmentDataset, names: list[str], progress: bool = True) -> FoldStore:
    """The detail mode's folds of the database sequences ``names`` (:mod:`hrr_garment.artifacts.folds`)."""
    mean = mean_operator(ds.template.faces, ds.template.num_vertices)
    return FoldStore.build(
        (body_frames(ds, [n]) for n in tqdm(names, desc="folds", unit="sequence", disable=not progress)), mean
    )


def _record_what_it_learned(
    folder: Path, manifest, ds: GarmentDataset, motion: dict, materials: dict
) -> None:
    """A finished model's records brought up to date: its motion's sources where missing (trained
    before they were recorded) or out of date (the dataset built again records them otherwise), and
    the cloth it learned where it was trained before cloths were recorded."""
    if "motion_sources" in ds.info and thawed(manifest.motion) != motion:
        update_manifest(folder, motion=motion)
    if manifest.materials is None:
        update_manifest(folder, materials=MaterialsEntry.parse(materials, "materials"))


def run_codespace_stage(
    dataset: str | Path,
    folder: str | Path,
    config: CodeSpaceSettings = CodeSpaceSettings(),
    train_config: CodeSpaceTrainSettings = CodeSpaceTrainSettings(),
    cache_dir: Path | None = None,
    progress: bool = True,
    info: dict | None = None,
) -> StageReport:
    """Train the code space and write the bundle in ``folder``; ``metrics`` is the stage's report.json."""
    t0 = time.perf_counter()
    folder = Path(folder)
    stage = folder / STAGE_FOLDER
    ds = GarmentDataset(dataset)
    check_splits(ds)
    # a model across bodies reads their measures, a model across cloths their values; a model of
    # one body or one cloth does not
    bodies, materials = training_bodies(ds), training_materials(ds)
    config = replace(
        config,
        body_features=len(BODY_MEASURES) if bodies and bodies["range"]["bodies"] > 1 else 0,
        material_features=len(MATERIAL_FEATURES) if materials["range"]["cloths"] > 1 else 0,
    )
    ae_folder = folder / "autoencoder"
    ae_meta, ae_state, latents = autoencoder_outputs(ds, dataset, ae_folder)
    key, training_key = stage_keys(config, train_config, ae_state, latents=latents, ds=ds)
    report_path = stage / "report.json"
    finished = finished_stage(folder, report_path, key)
    if finished is not None and cap_since_raised(
        finished[0]["training"].get("stopped"),
        finished[0]["training"]["config"].get("max_minutes"),
        train_config.max_minutes,
    ):
        finished = None  # cut short by a smaller cap: its checkpoint resumes
    done, manifest = finished if finished is not None else (None, None)
    # trained before the folds, or stored in an older encoding (int8, twice the size): (re)build them
    # alone, and drop the auto choice made without them
    if manifest is not None and (manifest.folds is None or manifest.folds.encoding != FOLD_ENCODING):
        folds = fold_store(ds, list(manifest.database.names), progress)
        add_bundle_part(folder, FOLDS_FILE, folds.arrays(), numpy=True, folds=folds.entry, auto=None)
    splits = {k: ds.splits[k] for k in ("train", "val")}
    motion = licences_of(splits["train"] + splits["val"], ds.info).to_dict()
    if manifest is not None:
        _record_what_it_learned(folder, manifest, ds, motion, materials)
    if manifest is not None and manifest.residual is not None:
        return _stage_report(done, stage, reused=True)
    features = dataset_features(ds, splits["train"] + splits["val"], config)
    train_w, val_w, motion_stats, latent_stats, calibration = codespace_windows(
        features, latents, splits, config=config, train_config=train_config
    )
    encoding = refine_settings(ae_meta.get("train", {}))
    val_names = sorted({n for n, _ in calibration}) if calibration else splits["val"]
    if done is not None:  # trained before the residual mode: calibrate it alone
        done = add_residual_mode(
            folder,
            report_path,
            done,
            ds=ds,
            features=features,
            val_names=val_names,
            calibration=calibration,
            cache_dir=cache_dir,
        )
        return _stage_report(done, stage, reused=True)

    autoencoder = load_autoencoder(ae_folder, ds.template.faces, cache_dir)
    train_t = WindowTensors.of(train_w, motion_stats, latent_stats)
    val_t = WindowTensors.of(val_w, motion_stats, latent_stats)

    latent_loss = mean_square
    if train_config.latent_loss == "vertex":
        latent_loss = VertexMetric.of_decoder(
            autoencoder,
            sample_frames(train_w.latents.frames, seed=train_config.seed),
            latent_stats.std,
            train_config.vertex_ridge,
            progress=progress,
        )
    torch.manual_seed(train_config.seed)
    model = CodeSpace(config, config.features, autoencoder.latent_shape)
    summary = train_codespace(
        model,
        train_t,
        val_t,
        folder=stage,
        config=train_config,
        key=training_key,
        progress=progress,
        latent_loss=latent_loss,
    )
    if train_config.contact_steps:
        summary["contact"] = teach_contact(
            model,
            FrameDecoder(autoencoder, latent_stats),
            ContactWindows(train_t, BodyContacts.of(ds, train_w, train_config.contact_body)),
            val=ContactWindows(val_t, BodyContacts.of(ds, val_w, train_config.contact_body)),
            config=train_config,
            latent_loss=latent_loss,
            checkpoint=(stage / "contact.pt", key),
            progress=progress,
        )

    # the database of every training window's garment code, then tau on the validation split
    database = CodeDatabase(
        garment_codes(model, train_t),
        train_w.latents,
        train_w.sequence,
        start=train_w.start,
        names=train_w.names,
        classes=config.classes,
        motion=train_w.motion.with_frames(train_t.motion.numpy()),
    )
    parts = BundleParts(
        autoencoder=autoencoder,
        codespace=model,
        motion_stats=motion_stats,
        latent_stats=latent_stats,
        database=database,
        template=ds.template,
        folds=fold_store(ds, train_w.names, progress),
    )
    modes = window_mode_errors(
        parts,
        {n: features[n] for n in val_names},
        {n: body_frames(ds, [n]) for n in val_names},
        encoding=encoding,
        windows=calibration,
        progress=progress,
    )
    gate, sweep = modes.gate, modes.sweep
    usage = model.quantizer.usage(torch.from_numpy(database.codes))
    final = evaluate(model, val_t)
    report = {
        "key": key,
        "windows": {"train": len(train_w), "val": len(val_w)},
        "training": summary,
        "validation_mm": modes.summary(sweep.best_tau, gate),
        "gate": gate,
        "tau": sweep.best_tau,
        "gates": modes.gates(),
        "sweep": sweep.to_dict(),
        "residual": modes.residual_calibration(),
        "code_agreement": final["agreement"],
        "chance_agreement": 1.0 / config.classes,
        "database_codes": {
            "dead_classes": usage.dead,
            "classes": usage.total,
            "perplexity": usage.perplexity,
            "distinct_codes": int(len(np.unique(database.codes, axis=0))),
        },
        "entropy_histogram": final["entropy_histogram"],
        "minutes": (time.perf_counter() - t0) / 60,
    }
    write_bundle(
        folder,
        parts,
        tau=sweep.best_tau,
        gate=gate,
        info={
            "dataset": str(dataset),
            "window": config.window,
            "validation_mm": report["validation_mm"],
            "gates": report["gates"],
            **({"residual": report["residual"]} if report["residual"] else {}),
            "encoding": encoding,
            "validation": train_config.validation,
            **({"bodies": bodies} if bodies else {}),
            "materials": materials,
            # where the clips it learned from (and its database stores) come from, and their terms
            "motion": motion,
            **(info or {}),
        },
    )
    atomic_write_text(report_path, strict_json(report, indent=2, default=float))
    return _stage_report(report, stage)
