"""The ``direct`` stage of ``hrr-train`` (formerly ``baseline``): the direct-regression baseline
(:mod:`..models.direct`).

Trained on the same data as the code space, in the same standardised spaces (the bundle's motion
and latent statistics, the autoencoder's latents of every frame), with the same kind of budget
(``direct.train.max_minutes``, by default the code-space stage's). Random crops of ``crop``
frames from the training sequences, L1 on the standardised latents, Adam; early stopping on the
validation sequences run whole. Checkpointed each epoch in ``MODEL/direct/`` and resumable; the
weights join the bundle as ``direct.safetensors`` with a ``direct`` entry in bundle.json.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from ..models.direct import DirectRegressor, DirectSettings
from ..settings import from_settings
from .bundle_stage import add_trained_part, decoded_pve_mm, part_inputs, part_report
from .checkpoint import Checkpoint, EpochLog
from .loop import Budget, Epoch, EpochStep, ProgressBar, TrainingRun, fit
from .report import StageReport
from .training_frames import body_frames


@dataclass(frozen=True)
class DirectTrainSettings:
    """The direct stage's training settings (``direct.train``)."""

    epochs: int = 300
    batch_size: int = 16
    crop: int = 60  # frames per training crop
    learning_rate: float = 1e-3
    weight_decay: float = 1e-4
    patience: int = 25  # epochs without a better validation loss
    max_minutes: float | None = None
    seed: int = 0

    @classmethod
    def from_dict(cls, values: dict) -> "DirectTrainSettings":
        return from_settings(cls, values, "direct training")


def _sequences(
    features: dict, latents: dict, names: list[str], bundle
) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
    motion = [torch.from_numpy(bundle.motion_stats.normalize(features[n]).astype(np.float32)) for n in names]
    lat = [
        torch.from_numpy(
            bundle.latent_stats.normalize(latents[n].reshape(len(latents[n]), -1)).astype(np.float32)
        )
        for n in names
    ]
    return motion, lat


def _crops(
    motion: list[torch.Tensor], latents: list[torch.Tensor], crop: int, batch: int, gen: torch.Generator
):
    """Batches of random crops: about one crop per ``crop`` frames of training data per epoch."""
    lengths = torch.tensor([len(m) for m in motion])
    picks = max(1, int(lengths.sum()) // crop)
    seq = torch.multinomial(lengths.float(), picks, replacement=True, generator=gen)
    for i in range(0, picks, batch):
        size = min(crop, int(lengths[seq[i : i + batch]].min()))
        xs, ys = [], []
        for s in seq[i : i + batch].tolist():
            start = int(torch.randint(0, len(motion[s]) - size + 1, (1,), generator=gen))
            xs.append(motion[s][start : start + size])
            ys.append(latents[s][start : start + size])
        yield torch.stack(xs), torch.stack(ys)


@torch.no_grad()
def _val_loss(model: DirectRegressor, motion: list[torch.Tensor], latents: list[torch.Tensor]) -> float:
    model.eval()
    total = sum(float((model(m[None])[0] - y).abs().sum()) for m, y in zip(motion, latents))
    return total / sum(y.numel() for y in latents)


class _BaselineEpochs(EpochStep):
    """The baseline's epoch: random crops of the training sequences, drawn by a generator seeded by
    the epoch, then the L1 loss on the validation sequences run whole."""

    def __init__(
        self,
        model: DirectRegressor,
        optimizer: torch.optim.Optimizer,
        data: tuple,
        config: DirectTrainSettings,
    ):
        self.model, self.optimizer, self.config = model, optimizer, config
        self.train, self.val = data

    def run_epoch(self, run: TrainingRun) -> Epoch:
        model, config = self.model, self.config
        model.train()
        gen = torch.Generator().manual_seed(config.seed + run.state["epoch"])
        total, count = 0.0, 0
        for x, y in _crops(*self.train, config.crop, config.batch_size, gen):
            loss = (model(x) - y).abs().mean()
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            total, count = total + loss.item() * len(x), count + len(x)
        val_loss = _val_loss(model, *self.val)
        return Epoch(
            val_loss, {"train_l1": total / max(count, 1), "val_l1": val_loss}, {"val": f"{val_loss:.3f}"}
        )


def train_direct(
    model: DirectRegressor,
    train: tuple,
    val: tuple,
    folder: Path,
    config: DirectTrainSettings,
    key: str,
    progress: bool = True,
) -> dict:
    """Train (or resume) the baseline in ``folder``; leaves the best weights in ``model``, returns the
    loop's state. Its patience counts from the first epoch, and its cap stops it once passed."""
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(config.seed)
    optimizer = torch.optim.Adam(
        model.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
    )
    budget = Budget(
        config.epochs, config.max_minutes, patience=config.patience, late_patience=False, whole_epochs=False
    )
    return fit(
        model,
        _BaselineEpochs(model, optimizer, (train, val), config),
        budget,
        callbacks=[
            EpochLog(folder / "log.jsonl"),
            Checkpoint(folder / "checkpoint.pt", key, optimizer=optimizer),
            ProgressBar("direct", progress),
        ],
    )


def run_direct_stage(
    dataset: str | Path,
    folder: str | Path,
    config: DirectSettings = DirectSettings(),
    train_config: DirectTrainSettings = DirectTrainSettings(),
    cache_dir: Path | None = None,
    progress: bool = True,
) -> StageReport:
    """Train the baseline for the bundle in ``folder`` (the code-space stage must have run);
    ``metrics`` is its ``direct`` entry in bundle.json."""
    t0 = time.perf_counter()
    folder = Path(folder)
    inputs, recorded = part_inputs(
        folder, dataset, cache_dir, part="direct", config=config, train=train_config
    )
    if recorded is not None:
        return part_report("direct", folder, recorded)
    bundle, names = inputs.bundle, inputs.names
    train = _sequences(inputs.features, inputs.latents, names["train"], bundle)
    val = _sequences(inputs.features, inputs.latents, names["val"], bundle)
    torch.manual_seed(train_config.seed)
    model = DirectRegressor(config, bundle.codespace.features, bundle.autoencoder.latent_shape)
    state = train_direct(model, train, val, folder / "direct", train_config, inputs.key, progress)
    val_mm = validation_pve_mm(model, bundle, val[0], body_frames(inputs.dataset, names["val"]))
    entry = {
        "key": inputs.key,
        "config": config.to_dict(),
        "train": asdict(train_config),
        "epochs": state["epoch"],
        "best_epoch": state["best_epoch"],
        "validation_mm": val_mm,
        "minutes": (time.perf_counter() - t0) / 60,
    }
    return add_trained_part(folder, "direct", model, entry=entry)


@torch.no_grad()
def validation_pve_mm(model: DirectRegressor, bundle, motion: list[torch.Tensor], truth: np.ndarray) -> float:
    """Per-vertex error (mm) in the heading frame over the validation frames, decoded."""
    return decoded_pve_mm(bundle, [model(m[None])[0].numpy() for m in motion], truth)
