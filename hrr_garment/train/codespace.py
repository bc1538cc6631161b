"""The code-space stage of ``hrr-train``: windows -> code space -> database -> tau -> bundle.

Reads the dataset and the autoencoder stage's outputs (``MODEL/autoencoder/``: weights and
latents of every frame), trains the code space in ``MODEL/codebook/`` (checkpointed, resumable;
the folder keeps the stage's old name so that models trained before the rename resume), builds
the retrieval database from every training window's garment code, calibrates tau on the
validation split (the hybrid's gate and the residual mode's weight), and writes the bundle at the
top of ``MODEL/`` (:mod:`hrr_garment.artifacts.bundle`). A re-run with nothing changed finds the
finished report and returns it without redoing anything (a bundle from before the residual mode
or the detail mode's folds only has what it lacks added).
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from ..artifacts.bundle import BundleError, load_bundle
from ..artifacts.bundle_writer import BundleParts, add_bundle_part, write_bundle
from ..artifacts.database import CodeDatabase
from ..artifacts.folds import FOLD_ENCODING, FoldStore
from ..artifacts.manifest import FOLDS_FILE
from ..artifacts.manifest_entries import ResidualEntry
from ..artifacts.typed_manifest import Manifest, read_manifest, update_manifest
from ..body.body_file import body_to_dict
from ..body.mannequin import MANNEQUIN
from ..body.measures import BODY_MEASURES, BodyRange, body_vector
from ..data.dataset import DatasetError, GarmentDataset
from ..data.windows import build_windows, dataset_features, fit_stats, split_windows
from ..garment.smoothing import mean_operator
from ..io_utils import atomic_write_text, strict_json
from ..models.codespace import CodeSpace, CodeSpaceSettings
from .autoencoder import body_frames, load_autoencoder, refine_settings
from .calibrate import calibrate_residual, window_mode_errors
from .codespace_training import (
    PAPER_VALIDATION_FRACTION,
    CodeSpaceTrainSettings,
    WindowTensors,
    evaluate,
    mean_square,
    train_codespace,
)
from .contact import BodyContacts, ContactWindows, FrameDecoder, teach_contact
from .report import StageReport
from .schedule import cap_since_raised
from .vertex_metric import VertexMetric, sample_frames

CONTACT_SETTINGS = (
    "contact_steps",
    "contact_weight",
    "contact_margin_m",
)  # the contact phase's: not the main training's key
NOT_TRAINING = (*CONTACT_SETTINGS, "target_mm")  # settings that leave the main training as it is
STAGE_FOLDER = "codebook"  # under MODEL/: the name from before "code space" was the stage's name


def check_splits(ds: GarmentDataset) -> None:
    """The code space needs training and validation sequences."""
    if not ds.splits.get("train") or not ds.splits.get("val"):
        raise DatasetError(
            ds.path,
            f"needs at least one training and one validation sequence; it has "
            f"{len(ds.splits.get('train', []))} and {len(ds.splits.get('val', []))} "
            f"({len(ds.names)} sequences in all: simulate at least 3)",
        )


@torch.no_grad()
def garment_codes(model: CodeSpace, windows: WindowTensors, batch: int = 512) -> np.ndarray:
    """Argmax garment codes (N, G) uint8 of standardised latent windows."""
    model.eval()
    out = []
    for i in range(0, len(windows), batch):  # the latent windows, and the body of a model across bodies
        motion, latents = windows[slice(i, i + batch)]
        out.append(model.quantizer.split(model.garment_encoder(latents, model.body_of(motion))).argmax(-1))
    return torch.cat(out).numpy().astype(np.uint8)


def training_bodies(ds: GarmentDataset) -> dict | None:
    """bundle.json's ``bodies`` of a model trained on ``ds``: the range of the bodies its training
    split was simulated on (:class:`~hrr_garment.body.measures.BodyRange`), the body it animates
    when given none (the one body of a model trained on one, the mannequin otherwise) and the body
    its garment was modelled on (``hrr-simulate --made-for``; None: the mannequin). None where the
    data is the mannequin's alone, as before bodies."""
    names = sorted({ds.body_of[n] for n in ds.splits["train"]})
    made_for = ds.info.get("made_for")
    if names == [MANNEQUIN] and ds.bodies[MANNEQUIN].is_mannequin and made_for is None:
        return None
    known = BodyRange.of([body_vector(ds.bodies[n].record) for n in names])
    return {
        "range": known.to_dict(),
        "default": body_to_dict(ds.bodies[names[0]].record) if len(names) == 1 else None,
        "made_for": made_for,
    }


def _autoencoder_outputs(
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


def _stage_key(
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
    return hashlib.sha1(
        json.dumps([config.to_dict(), training, ae_hash, ds.splits], sort_keys=True).encode()
    ).hexdigest()[:16]


def _stage_keys(
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
    training = _stage_key(config, train_config, ae_state, latents, ds)
    if train_config.contact_steps == 0:
        return training, training
    settings = json.dumps([training, {k: getattr(train_config, k) for k in CONTACT_SETTINGS}], sort_keys=True)
    return hashlib.sha1(settings.encode()).hexdigest()[:16], training


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


def _finished(folder: Path, report_path: Path, key: str) -> tuple[dict, Manifest] | None:
    """The report and bundle.json of a finished stage with these settings whose bundle is intact, else None."""
    if not (report_path.is_file() and (folder / "bundle.json").is_file()):
        return None
    report = json.loads(report_path.read_text())
    if report.get("key") != key:
        return None
    try:
        return report, read_manifest(folder)
    except BundleError:  # a damaged bundle is rebuilt
        return None


def fold_store(ds: GarmentDataset, names: list[str], progress: bool = True) -> FoldStore:
    """The detail mode's folds of the database sequences ``names`` (:mod:`hrr_garment.artifacts.folds`)."""
    mean = mean_operator(ds.template.faces, ds.template.num_vertices)
    return FoldStore.build(
        (body_frames(ds, [n]) for n in tqdm(names, desc="folds", unit="sequence", disable=not progress)), mean
    )


def _windows(
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


def _add_residual(
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
    bodies = training_bodies(ds)  # a model across bodies reads their measures; a model of one body does not
    config = replace(
        config, body_features=len(BODY_MEASURES) if bodies and bodies["range"]["bodies"] > 1 else 0
    )
    ae_folder = folder / "autoencoder"
    ae_meta, ae_state, latents = _autoencoder_outputs(ds, dataset, ae_folder)
    key, training_key = _stage_keys(config, train_config, ae_state, latents, ds)
    report_path = stage / "report.json"
    finished = _finished(folder, report_path, key)
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
    if manifest is not None and manifest.residual is not None:
        return _stage_report(done, stage, reused=True)
    splits = {k: ds.splits[k] for k in ("train", "val")}
    features = dataset_features(
        ds, splits["train"] + splits["val"], config.memory, body_measures=config.body_features > 0
    )
    train_w, val_w, motion_stats, latent_stats, calibration = _windows(
        features, latents, splits, config, train_config
    )
    encoding = refine_settings(ae_meta.get("train", {}))
    val_names = sorted({n for n, _ in calibration}) if calibration else splits["val"]
    if done is not None:  # trained before the residual mode: calibrate it alone
        done = _add_residual(folder, report_path, done, ds, features, val_names, calibration, cache_dir)
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
            ContactWindows(train_t, BodyContacts.of(ds, train_w)),
            val=ContactWindows(val_t, BodyContacts.of(ds, val_w)),
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
            **(info or {}),
        },
    )
    atomic_write_text(report_path, strict_json(report, indent=2, default=float))
    return _stage_report(report, stage)
