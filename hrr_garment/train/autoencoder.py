"""Training the mesh autoencoder on a garment dataset, then encoding every frame to latents.

Vertices are expressed in the body frame (:mod:`hrr_garment.motion.frame`: origin following the
pelvis, Z along its heading), where a garment's shape depends on the pose but not on where the body
is or which way it faces. Loss: L1 on vertex positions plus ``laplacian`` x L1 on uniform Laplacian
coordinates (keeps the surface smooth between vertices). Adam with a cosine learning-rate schedule
over the run (:func:`set_learning_rate`), early stopping on the validation split's per-vertex error,
a checkpoint after every epoch (a re-run resumes from it), seeded. Every frame is then encoded, each
latent refined by a few gradient steps through the decoder (``MeshAutoencoder.fit_latents``); the
report's errors are those of the refined latents, the encoder's own in ``extra``.

Outputs in the model folder (``autoencoder/``): ``config.json``, ``model.pt`` (the best weights,
a plain state dict), ``checkpoint.pt`` (for resuming), ``latents.npz`` (per sequence (T, N, 8)),
``report.json``. The settings are in :mod:`.autoencoder_settings`, the frames it learns (in the
body frame, mirrored) in :mod:`.training_frames`.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ..data.dataset import GarmentDataset
from ..io_utils import atomic_path, atomic_write_text, strict_json
from ..models.fcmae import AutoencoderSettings, MeshAutoencoder
from ..models.hierarchy import cached_hierarchy
from ..motion.frame import FRAME_VERSION
from .autoencoder_settings import AutoencoderTrainSettings, refine_settings
from .checkpoint import Checkpoint
from .loop import Budget, Epoch, EpochStep, ProgressBar, TrainingRun, fit
from .mesh_loss import apply_laplacian, laplacian_operator, pve_mm
from .report import StageReport
from .schedule import cap_since_raised, set_learning_rate, training_device
from .training_frames import TrainingFrames, body_frames, training_frames


def _key(*parts) -> str:
    return hashlib.sha1(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _settings_keys(
    model_config: AutoencoderSettings, train_config: AutoencoderTrainSettings, ds: GarmentDataset
) -> tuple[str, str]:
    """(training key, stage key). The checkpoint's key leaves out what only the encoding uses:
    changing the refinement re-encodes a finished run (its checkpoint is at the end of training)
    instead of training it again. The objective was L1 per coordinate before: those latents
    re-encode. The stage key also holds what the dataset holds (:meth:`GarmentDataset.content_key`):
    latents are of one dataset's frames, and a dataset made again under the same names (its stops
    held longer, another cloth) re-encodes them."""
    encoding = refine_settings(asdict(train_config)) | {"refine_objective": "vertex distance"}
    training = {k: v for k, v in asdict(train_config).items() if k not in encoding and k != "target_mm"}
    training_key = _key(
        model_config.to_dict(),
        training | {"max_minutes": None, "threads": None, "device": None},
        ds.garment,
        ds.template.num_vertices,
        ds.splits,
        {"frame": FRAME_VERSION},
    )
    return training_key, _key(training_key, encoding, ds.content_key())


def _stage_report(record: dict, folder: Path, reused: bool = False) -> StageReport:
    """The StageReport of a report.json record (``key`` left out)."""
    metrics = {
        k: v for k, v in record.items() if k not in ("key", "folder", "epochs", "best_epoch", "minutes")
    }
    metrics["latent_shape"], metrics["sizes"] = tuple(metrics["latent_shape"]), tuple(metrics["sizes"])
    if reused:
        metrics["extra"] = {**metrics.get("extra", {}), "reused": True}
    return StageReport.of_record(
        "autoencoder",
        folder,
        record,
        reused=reused,
        metrics=metrics,
        epochs_asked=record.get("epochs_asked"),
        stopped=record.get("stopped"),
        validation_mm=record.get("val_pve_mm"),
    )


def _finished(folder: Path, key: str) -> dict | None:
    """report.json of a run finished with these settings (its outputs all there), else None."""
    report_path = folder / "report.json"
    if report_path.is_file() and (folder / "latents.npz").is_file() and (folder / "model.pt").is_file():
        done = json.loads(report_path.read_text())
        if done.get("key") == key:
            return done
    return None


class _AutoencoderEpochs(EpochStep):
    """The autoencoder's epoch: a fresh sample of training frames in batches, the cosine rate set
    before each, then the validation split's per-vertex error (mm)."""

    def __init__(
        self,
        model: MeshAutoencoder,
        optimizer: torch.optim.Optimizer,
        frames: TrainingFrames,
        config: AutoencoderTrainSettings,
        device: torch.device,
    ):
        self.model, self.optimizer, self.frames = model, optimizer, frames
        self.config, self.device = config, device
        conv0 = model.encoder[0].conv
        self.lap = laplacian_operator(conv0.index.cpu(), conv0.mask.cpu()).to(device)

    def start(self, run: TrainingRun) -> None:
        self.rng = np.random.default_rng(self.config.seed + run.state["epoch"])

    def run_epoch(self, run: TrainingRun) -> Epoch:
        model, optimizer, config, train = self.model, self.optimizer, self.config, self.frames.train
        model.train()
        # a bounded epoch: one pass over the real-motion library's 114,000 frames took 18 min on
        # 2 cores, longer than its whole budget, so validation, checkpoints and the budget check
        # would wait for it; each epoch draws a fresh sample instead
        order = self.rng.permutation(len(train))[: config.frames_per_epoch]
        losses = []
        for i in range(0, len(order), config.batch_size):
            set_learning_rate(optimizer, config, run.progress(run.state["epoch"] + i / len(order)))
            x = torch.from_numpy(train[order[i : i + config.batch_size]]).to(self.device)
            y = model(x)
            loss = (y - x).abs().mean() + config.laplacian * (apply_laplacian(self.lap, y - x)).abs().mean()
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
        model.eval()
        val_err = pve_mm(model, self.frames.val if len(self.frames.val) else train[:256])
        return Epoch(val_err, postfix={"loss": f"{np.mean(losses) * 1000:.2f}mm", "val": f"{val_err:.2f}mm"})


def train_autoencoder(
    dataset: str | Path,
    folder: str | Path,
    model_config: AutoencoderSettings = AutoencoderSettings(),
    train_config: AutoencoderTrainSettings = AutoencoderTrainSettings(),
    cache_dir: Path | None = None,
    progress: bool = True,
) -> StageReport:
    """Train (or resume), keep the best weights, encode every sequence. See the module docstring.
    ``metrics``: the per-vertex errors (val, test, train; mm), latent shape, levels and ``extra``."""
    t_start = time.perf_counter()
    device = training_device(train_config.device)  # before anything is written
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(train_config.seed)
    if train_config.threads:
        torch.set_num_threads(train_config.threads)
    ds = GarmentDataset(dataset)
    frames = training_frames(ds, train_config.mirror)
    hierarchy = cached_hierarchy(
        ds.template.faces,
        ds.template.num_vertices,
        cache_dir,
        **model_config.hierarchy_options(),
        name=str(dataset),
    )
    model = MeshAutoencoder(
        hierarchy, model_config, ds.template.vertices.astype(np.float32), scale=frames.scale
    ).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=train_config.learning_rate)
    training_key, key = _settings_keys(model_config, train_config, ds)
    done = _finished(folder, key)
    if done is not None and not cap_since_raised(
        done.get("stopped"), done.get("cap_minutes"), train_config.max_minutes
    ):
        # finished with these settings: nothing to redo
        return _stage_report(done, folder, reused=True)
    state = fit(
        model,
        _AutoencoderEpochs(model, optimizer, frames, train_config, device),
        Budget(train_config.epochs, train_config.max_minutes, patience=train_config.patience),
        callbacks=[
            Checkpoint(folder / "checkpoint.pt", training_key, optimizer=optimizer),
            ProgressBar("autoencoder", progress, best="{:.2f}mm"),
        ],
    )
    # encoding (the refinement's decoder passes) runs on the training device, the rest on the CPU,
    # where inference will
    latents = encode_dataset(
        model,
        ds,
        folder / "latents.npz",
        train_config.refine_steps,
        train_config.refine_lr,
        progress=progress,
    )
    model.cpu()
    with atomic_path(folder / "model.pt") as tmp:
        torch.save(model.state_dict(), tmp)
    atomic_write_text(
        folder / "config.json",
        json.dumps(
            {
                "model": model_config.to_dict(),
                "train": asdict(train_config),
                "dataset": str(dataset),
                "garment": ds.garment,
                "vertices": ds.template.num_vertices,
                "scale": frames.scale,
                "sizes": list(hierarchy.sizes),
            },
            indent=2,
        ),
    )

    def refined_pve(split: str, split_frames: np.ndarray, every: int = 1) -> float:
        """``split_frames``: the split's frames in ``ds.splits`` order, as ``latents`` holds them."""
        names = ds.splits.get(split, [])
        if not names:
            return float("nan")
        return pve_mm(model, split_frames[::every], np.concatenate([latents[n] for n in names])[::every])

    record = {
        "key": key,
        "folder": str(folder),
        "epochs": state["epoch"],
        "best_epoch": state["best_epoch"],
        "epochs_asked": train_config.epochs,
        "stopped": state["stopped"],
        "cap_minutes": train_config.max_minutes,
        "val_pve_mm": refined_pve("val", frames.val),
        "test_pve_mm": refined_pve("test", frames.test),
        "train_pve_mm": refined_pve("train", frames.train[: frames.simulated], every=4),
        "minutes": (time.perf_counter() - t_start) / 60,
        "latent_shape": model.latent_shape,
        "sizes": hierarchy.sizes,
        "extra": {
            "refine_steps": train_config.refine_steps,
            "encoder_only_mm": {"val": state["best"], "test": pve_mm(model, frames.test)},
        },
    }
    atomic_write_text(folder / "report.json", strict_json(record, indent=2))
    return _stage_report(record, folder)


def encode_dataset(
    model: MeshAutoencoder,
    ds: GarmentDataset,
    path: Path,
    refine_steps: int = 10,
    refine_lr: float = 0.03,
    progress: bool = True,
) -> dict[str, np.ndarray]:
    """Latents (T, N, 8) float32 of every sequence (``fit_latents``), written to ``path`` as one
    npz entry per sequence name, and returned."""
    latents = {}
    for name in tqdm(ds.names, desc="encoding", unit="sequence", disable=not progress):
        frames = torch.from_numpy(body_frames(ds, [name])).to(model.template.device)
        latents[name] = model.fit_latents(frames, refine_steps, refine_lr).cpu().numpy()
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **latents)
    return latents


def load_autoencoder(folder: str | Path, faces: np.ndarray, cache_dir: Path | None = None) -> MeshAutoencoder:
    """The trained model of ``folder`` (weights only; no pickled objects are loaded)."""
    folder = Path(folder)
    meta = json.loads((folder / "config.json").read_text())
    config = AutoencoderSettings.from_dict(meta["model"])
    hierarchy = cached_hierarchy(faces, meta["vertices"], cache_dir, **config.hierarchy_options())
    model = MeshAutoencoder(hierarchy, config)
    state = torch.load(folder / "model.pt", map_location="cpu", weights_only=True)
    # files from before the neighbour lists stopped being saved (they are rebuilt from the template)
    state = {k: v for k, v in state.items() if not k.endswith((".index", ".mask"))}
    model.load_state_dict(state)
    return model.eval()
