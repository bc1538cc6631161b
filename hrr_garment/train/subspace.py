"""The ``subspace`` stage of ``hrr-train``: the run-time decoder sized for games
(:class:`~hrr_garment.models.subspace.SubspaceDecoder`), distilled from the bundle's mesh decoder.

1. The training frames' latents (the autoencoder stage's ``latents.npz``) are decoded by the full
   decoder; the principal components of those outputs (a sample of at most ``pca_frames``) make the
   basis, and every frame's coefficients on it the targets.
2. A small network learns latents -> coefficients (standardised; the loss weighs each by its
   variance, so it is the squared vertex error within the subspace), Adam with a cosine schedule,
   ``epochs`` passes, the best validation epoch kept; checkpointed each epoch in ``MODEL/subspace/``.
3. On the validation sequences, the full decoder's error against the simulation and the fast
   decoder's at each candidate size (:mod:`.subspace_size`): the fewest components whose error is at most
   ``tolerance`` times the full decoder's are kept (else the fewest within 1 % of the most accurate), recorded
   in bundle.json ``subspace`` beside every candidate's number, and the weights join the bundle as
   ``subspace.safetensors``.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from ..artifacts.bundle_writer import add_bundle_part
from ..artifacts.manifest import SUBSPACE_FILE
from ..artifacts.manifest_entries import SubspaceEntry
from ..data.dataset import DatasetError
from ..io_utils import atomic_write_text, strict_json
from ..models.subspace import SubspaceDecoder, SubspaceSettings, principal_components
from ..settings import from_settings, require_number
from .bundle_stage import bundle_and_dataset
from .checkpoint import Checkpoint, EpochLog
from .loop import Budget, Epoch, EpochStep, ProgressBar, TrainingRun, fit
from .report import StageReport
from .subspace_size import pick_components, validation_errors
from .training_frames import body_frames

STAGE_VERSION = (
    2  # moves when the stage would give another result from the same inputs (2: the size's fallback)
)


@dataclass(frozen=True)
class SubspaceTrainSettings:
    """The subspace stage's training settings (``subspace.train``)."""

    epochs: int = 60
    batch_size: int = 512
    learning_rate: float = 1e-3
    pca_frames: int = 20_000  # training frames sampled for the principal components
    # kept: the fewest components whose validation error (mm, against the simulation) is at most
    # this times the full decoder's (a few tenths of a millimetre on an autoencoder's 3 mm, against
    # a model's 25-35 mm error from motion)
    tolerance: float = 1.1
    seed: int = 0

    def __post_init__(self) -> None:
        for name, high in (("epochs", 10_000), ("batch_size", 1 << 16), ("pca_frames", 10_000_000)):
            require_number("subspace training", name, getattr(self, name), low=1, high=high, whole=True)
        require_number("subspace training", "learning_rate", self.learning_rate, low=0, high=1, above=True)
        require_number("subspace training", "tolerance", self.tolerance, low=1, high=10)

    @classmethod
    def from_dict(cls, values: dict) -> "SubspaceTrainSettings":
        return from_settings(cls, values, "subspace training")


@torch.no_grad()
def _decode(decoder, latents: np.ndarray, batch: int = 256) -> np.ndarray:
    """(F, N, C) latents -> (F, V, 3) vertices through ``decoder`` (either kind), ``batch`` frames at a
    time."""
    return np.concatenate(
        [
            decoder(torch.from_numpy(np.ascontiguousarray(latents[i : i + batch]))).numpy()
            for i in range(0, len(latents), batch)
        ]
    )


def _project(frames: np.ndarray, basis: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(F, V, 3) frames -> (F, K) their coefficients on ``basis`` (its mean and rows)."""
    mean, rows = basis
    return (frames.reshape(len(frames), -1) - mean) @ rows.T


def _coefficients(
    decoder, latents: np.ndarray, basis: tuple[np.ndarray, np.ndarray], progress: bool, batch: int = 1024
) -> np.ndarray:
    """(F, K) coefficients of the full decoder's outputs on ``basis`` (its mean and rows), chunk by
    chunk: the training frames' outputs are never all held at once."""
    out = np.empty((len(latents), len(basis[1])), np.float32)
    for i in tqdm(
        range(0, len(latents), batch),
        desc="subspace targets",
        unit="chunk",
        leave=False,
        disable=not progress,
    ):
        out[i : i + batch] = _project(_decode(decoder, latents[i : i + batch]), basis)
    return out


class _SubspaceEpochs(EpochStep):
    """The fast decoder's epoch: every training frame in an order seeded by the epoch, in batches
    (the cosine schedule stepped after each), then the validation loss. The loss weighs each
    standardised coefficient by its share of the vertex error (``weight``)."""

    def __init__(
        self,
        model: SubspaceDecoder,
        optimizer: torch.optim.Optimizer,
        schedule: torch.optim.lr_scheduler.LRScheduler,
        data: tuple[tuple[torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]],
        config: SubspaceTrainSettings,
    ):
        self.model, self.optimizer, self.schedule, self.config = model, optimizer, schedule, config
        (self.inputs, self.targets), self.val = data
        self.weight = model.coeff_std**2 / (model.coeff_std**2).sum()

    def run_epoch(self, run: TrainingRun) -> Epoch:
        model, config, inputs, targets = self.model, self.config, self.inputs, self.targets
        model.train()
        order = torch.randperm(
            len(inputs), generator=torch.Generator().manual_seed(config.seed + run.state["epoch"])
        )
        total = 0.0
        for i in range(0, len(order), config.batch_size):
            rows = order[i : i + config.batch_size]
            loss = (((model.net(inputs[rows]) - targets[rows]) ** 2) * self.weight).sum(1).mean()
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            self.schedule.step()
            total += loss.item() * len(rows)
        model.eval()
        with torch.no_grad():
            val_loss = float((((model.net(self.val[0]) - self.val[1]) ** 2) * self.weight).sum(1).mean())
        return Epoch(val_loss, {"train": total / len(inputs), "val": val_loss}, {"val": f"{val_loss:.4f}"})


def _fit(
    model: SubspaceDecoder,
    inputs: torch.Tensor,
    targets: torch.Tensor,
    val: tuple[torch.Tensor, torch.Tensor],
    folder: Path,
    config: SubspaceTrainSettings,
    key: str,
    progress: bool,
) -> dict:
    """Train ``model.net`` on standardised (inputs, targets); the best validation epoch's weights are left in
    it."""
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(config.seed)
    optimizer = torch.optim.Adam(model.net.parameters(), lr=config.learning_rate)
    steps = config.epochs * math.ceil(len(inputs) / config.batch_size)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, T_max=steps)
    return fit(
        model,
        _SubspaceEpochs(model, optimizer, schedule, ((inputs, targets), val), config),
        Budget(config.epochs),
        callbacks=[
            EpochLog(folder / "log.jsonl"),
            Checkpoint(folder / "checkpoint.pt", key, optimizer=optimizer, schedule=schedule),
            ProgressBar("subspace", progress),
        ],
    )


def run_subspace_stage(
    dataset: str | Path,
    folder: str | Path,
    config: SubspaceSettings = SubspaceSettings(),
    train_config: SubspaceTrainSettings = SubspaceTrainSettings(),
    cache_dir: Path | None = None,
    progress: bool = True,
) -> StageReport:
    """Distil the subspace decoder for the bundle in ``folder`` (the code-space stage must have run);
    its ``subspace`` entry in bundle.json is the report's ``metrics``."""
    t0 = time.perf_counter()
    folder = Path(folder)
    bundle, ds = bundle_and_dataset(folder, dataset, cache_dir)
    names = {k: ds.splits[k] for k in ("train", "val")}
    if not names["val"]:
        raise DatasetError(
            dataset, "has no validation sequences: the subspace decoder's size is chosen on them"
        )
    key = hashlib.sha1(
        json.dumps(
            [
                STAGE_VERSION,
                config.to_dict(),
                asdict(train_config),
                bundle.manifest.files["autoencoder.safetensors"],
                ds.splits,
            ],
            sort_keys=True,
        ).encode()
    ).hexdigest()[:16]
    recorded = bundle.manifest.subspace
    if recorded is not None and recorded.key == key:
        return _stage_report({**recorded.to_dict(), "reused": True}, folder, reused=True)
    with np.load(folder / "autoencoder" / "latents.npz", allow_pickle=False) as f:
        latents = {
            split: np.concatenate([f[n] for n in split_names]).astype(np.float32)
            for split, split_names in names.items()
        }
    full = bundle.autoencoder.inference_decoder()
    rng = np.random.default_rng(train_config.seed)
    sample = np.sort(
        rng.choice(len(latents["train"]), min(train_config.pca_frames, len(latents["train"])), replace=False)
    )
    mean, basis, spread = principal_components(_decode(full, latents["train"][sample]), config.max_components)
    model = SubspaceDecoder(
        bundle.autoencoder.latent_shape, bundle.template.num_vertices, len(basis), config=config
    )
    flat = latents["train"].reshape(len(latents["train"]), -1)
    model.latent_mean.copy_(torch.from_numpy(flat.mean(0)))
    model.latent_std.copy_(torch.from_numpy(np.maximum(flat.std(0), 1e-6)))
    model.mean.copy_(torch.from_numpy(mean))
    model.basis.copy_(torch.from_numpy(basis))
    model.coeff_std.copy_(torch.from_numpy(spread))

    def standardised(split: str, coefficients: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        z = torch.from_numpy(latents[split])
        x = ((z.reshape(len(z), -1) - model.latent_mean) / model.latent_std).contiguous()
        return x, torch.from_numpy(coefficients / spread)

    val_frames = _decode(full, latents["val"])  # the targets on validation and the full decoder's own error
    state = _fit(
        model,
        *standardised("train", _coefficients(full, latents["train"], (mean, basis), progress)),
        standardised("val", _project(val_frames, (mean, basis))),
        folder / "subspace",
        train_config,
        key,
        progress,
    )
    truth = body_frames(ds, names["val"])
    full_mm = 1000.0 * float(np.linalg.norm(val_frames - truth, axis=-1).mean())
    errors = validation_errors(model, latents["val"], truth)
    kept = pick_components(errors, full_mm, train_config.tolerance)
    model = model.truncated(kept)
    entry = {
        "key": key,
        "config": config.to_dict(),
        "train": asdict(train_config),
        "components": kept,
        "epochs": state["epoch"],
        "best_epoch": state["best_epoch"],
        "full_validation_mm": full_mm,
        "validation_mm": errors[kept],
        "candidates_mm": {str(k): v for k, v in errors.items()},
        "minutes": (time.perf_counter() - t0) / 60,
    }
    add_bundle_part(
        folder,
        SUBSPACE_FILE,
        {k: v.contiguous() for k, v in model.state_dict().items()},
        subspace=SubspaceEntry.from_report(entry, "subspace"),
    )
    atomic_write_text(folder / "subspace" / "report.json", strict_json(entry, indent=2))
    return _stage_report(entry, folder)


def _stage_report(entry: dict, folder: Path, reused: bool = False) -> StageReport:
    return StageReport.of_record(
        "subspace", folder / "subspace", entry, reused=reused, validation_mm=float(entry["validation_mm"])
    )
