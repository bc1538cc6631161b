"""The ``sampler`` stage of ``hrr-train``: the generative decoder (:mod:`..models.sampler`, mode
``sample``).

Trained after the code space, on its training sequences: each frame's condition is what the
sampler sees at run time (the regression's causal latents, from the window ending at the frame;
the frame's motion features), its target the frame's departure from those latents in the
autoencoder's standardised latent space, scaled by the departures' spread over the training frames.
With a ``history`` (off by default: its roll-out drifts), the previous frames' departures are the
truth's (teacher forcing) with a little Gaussian noise (``history_noise``). Flow matching's loss,
Adam; early stopping on the validation frames' loss at fixed noise and times; then the draw's
temperature and pole calibrated on the validation clips (:mod:`.sampler_calibration`).
Checkpointed each epoch in ``MODEL/sampler/`` and resumable; the weights join the bundle as
``sampler.safetensors`` with a ``sampler`` entry in bundle.json, whose ``validation_mm`` is a
seeded draw of the validation sequences (against their one simulation: a sample is judged against
the truth's ensemble by ``hrr-eval``, this only tells a broken training).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ..models.codes import encode_motion
from ..models.sampler import ClothSampler, SamplerSettings
from ..motion.windows import causal_windows
from ..settings import from_settings
from .bundle_stage import add_trained_part, decoded_pve_mm, part_inputs, part_key, part_report
from .checkpoint import Checkpoint, EpochLog
from .contact import BodyContacts, FrameDecoder
from .loop import Budget, Epoch, EpochStep, ProgressBar, TrainingRun, fit
from .report import StageReport
from .sampler_calibration import calibrate_draws
from .sampler_contact import teach_sampler_contact
from .training_frames import body_frames

SCALE_FLOOR = 1e-3  # the smallest spread a latent value's departures are scaled by


@dataclass(frozen=True)
class SamplerTrainSettings:
    """The sampler stage's training settings (``sampler.train``)."""

    epochs: int = 60
    batch_size: int = 256
    learning_rate: float = 3e-4
    weight_decay: float = 1e-4  # with the lower rate: 36 epochs to the best, not 7 (it overfitted)
    patience: int = 8  # epochs without a better validation loss
    history_noise: float = 0.1  # Gaussian noise on the history's scaled departures in training
    max_minutes: float | None = None
    seed: int = 0
    # the contact phase after the flow's training (.sampler_contact): Adam steps on the sampler with
    # its draws' depth inside the body in the loss (0: none), that depth's weight (mm) beside the
    # flow's loss, and how far outside the body it is counted from (metres: a clearance)
    contact_steps: int = 300
    contact_weight: float = 2.0
    contact_margin_m: float = 0.002
    # the weight of the draws' mean squared distance to the trained flow's draws (scaled departures):
    # what keeps the draw where it was away from the body (sampler_contact.py)
    contact_anchor: float = 1.0

    def flow_settings(self) -> dict:
        """The settings the flow's training depends on (the contact phase's apart: a phase changed
        resumes from the trained flow, as the key of its checkpoint stays)."""
        return {k: v for k, v in asdict(self).items() if not k.startswith("contact_")}

    @classmethod
    def from_dict(cls, values: dict) -> "SamplerTrainSettings":
        return from_settings(cls, values, "sampler training")


@dataclass
class SamplerFrames:
    """Sequences' frames as the sampler learns them, one row a frame, sequences one after another."""

    features: torch.Tensor  # (N, F) standardised motion features
    mean: torch.Tensor  # (N, L) the regression's causal latents, standardised
    departure: torch.Tensor  # (N, L) the truth's latents less ``mean`` (standardised, not yet scaled)
    position: torch.Tensor  # (N,) the frame's index in its sequence
    lengths: list[int]  # frames of each sequence

    def sequences(self, values: torch.Tensor) -> list[torch.Tensor]:
        """``values`` (N, ...) cut into the sequences."""
        return list(torch.split(values, self.lengths))


def regression_latents(bundle, features: np.ndarray) -> np.ndarray:
    """The regression's standardised latents (T, nodes x C) of each frame from the window ending at
    it: what the sampler starts from at run time (mode ``sample`` is causal)."""
    window = bundle.codespace.config.window
    codes = encode_motion(
        bundle.codespace,
        bundle.motion_stats,
        bundle.latent_stats,
        motion_windows=causal_windows(features, window),
        last_frame=True,
    )
    latents = codes.regression[:, 0]
    return bundle.latent_stats.normalize(latents.reshape(len(latents), -1)).astype(np.float32)


def sampler_frames(bundle, features: dict, latents: dict, names: list[str], progress: bool) -> SamplerFrames:
    """The named sequences' :class:`SamplerFrames` (``latents``: the autoencoder's, per sequence)."""
    feats, means, departures, positions = [], [], [], []
    for name in tqdm(names, desc="sampler: regression latents", disable=not progress, leave=False):
        mean = regression_latents(bundle, features[name])
        truth = bundle.latent_stats.normalize(latents[name].reshape(len(mean), -1)).astype(np.float32)
        feats.append(bundle.motion_stats.normalize(features[name]).astype(np.float32))
        means.append(mean)
        departures.append(truth - mean)
        positions.append(np.arange(len(mean)))
    return SamplerFrames(
        *(torch.from_numpy(np.concatenate(a)) for a in (feats, means, departures, positions)),
        [len(m) for m in means],
    )


def sampler_batch(model: ClothSampler, frames: SamplerFrames, rows: torch.Tensor, history_noise: float, gen):
    """The condition's context and the scaled target of frames ``rows``: the previous frames'
    departures from the truth (zeros before a sequence's start) with ``history_noise``, and the
    frame's departure."""
    position = frames.position[rows]
    previous = torch.where(position >= 1, rows - 1, rows)
    history = []
    for k in range(1, model.config.history + 1):
        held = (position >= k)[:, None].to(frames.departure.dtype)
        past = frames.departure[torch.clamp(rows - k, min=0)] / model.residual_scale * held
        history.append(past + history_noise * held * torch.randn(past.shape, generator=gen))
    history = torch.stack(history, 1) if history else torch.zeros(len(rows), 0, frames.departure.shape[1])
    context = model.context(frames.features[rows], frames.mean[rows], frames.mean[previous], history)
    return context, frames.departure[rows] / model.residual_scale


class _SamplerEpochs(EpochStep):
    """An epoch: the training frames in a seeded random order, then the validation frames' loss at
    noise and times fixed for the whole training (so epochs compare)."""

    def __init__(self, model: ClothSampler, optimizer, data: tuple, config: SamplerTrainSettings):
        self.model, self.optimizer, self.config = model, optimizer, config
        self.train, self.val = data

    def run_epoch(self, run: TrainingRun) -> Epoch:
        model, config = self.model, self.config
        model.train()
        gen = torch.Generator().manual_seed(config.seed + run.state["epoch"])
        order = torch.randperm(len(self.train.mean), generator=gen)
        total, count = 0.0, 0
        for i in range(0, len(order), config.batch_size):
            rows = order[i : i + config.batch_size]
            context, target = sampler_batch(model, self.train, rows, config.history_noise, gen)
            noise = torch.randn(target.shape, generator=gen)
            loss = model.flow_loss(context, target, noise, torch.rand(len(rows), generator=gen))
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            total, count = total + loss.item() * len(rows), count + len(rows)
        val_loss = validation_loss(model, self.val, config.seed)
        return Epoch(
            val_loss, {"train_flow": total / max(count, 1), "val_flow": val_loss}, {"val": f"{val_loss:.3f}"}
        )


@torch.no_grad()
def validation_loss(model: ClothSampler, frames: SamplerFrames, seed: int, batch: int = 4096) -> float:
    """Flow matching's loss over ``frames`` at seeded noise and times (no history noise)."""
    model.eval()
    gen = torch.Generator().manual_seed(seed + 7919)
    total = 0.0
    for i in range(0, len(frames.mean), batch):
        rows = torch.arange(i, min(i + batch, len(frames.mean)))
        context, target = sampler_batch(model, frames, rows, 0.0, gen)
        noise = torch.randn(target.shape, generator=gen)
        tau = torch.rand(len(rows), generator=gen)
        total += float(model.flow_loss(context, target, noise, tau)) * len(rows)
    return total / max(len(frames.mean), 1)


def departure_scale(frames: SamplerFrames) -> torch.Tensor:
    """The spread of each latent value's departures over ``frames`` (at least :data:`SCALE_FLOOR`)."""
    return frames.departure.std(0).clamp_min(SCALE_FLOOR)


def train_sampler(
    model: ClothSampler, data: tuple, folder: Path, config: SamplerTrainSettings, key: str, progress: bool
) -> dict:
    """Train (or resume) the sampler in ``folder`` on ``data`` (train, val :class:`SamplerFrames`);
    leaves the best weights in ``model``, returns the loop's state."""
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(config.seed)
    model.residual_scale.copy_(departure_scale(data[0]))
    optimizer = torch.optim.Adam(
        model.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
    )
    budget = Budget(
        config.epochs, config.max_minutes, patience=config.patience, late_patience=False, whole_epochs=False
    )
    return fit(
        model,
        _SamplerEpochs(model, optimizer, data, config),
        budget,
        callbacks=[
            EpochLog(folder / "log.jsonl"),
            Checkpoint(folder / "checkpoint.pt", key, optimizer=optimizer),
            ProgressBar("sampler", progress),
        ],
    )


def run_sampler_stage(
    dataset: str | Path,
    folder: str | Path,
    config: SamplerSettings = SamplerSettings(),
    train_config: SamplerTrainSettings = SamplerTrainSettings(),
    cache_dir: Path | None = None,
    progress: bool = True,
) -> StageReport:
    """Train the sampler for the bundle in ``folder`` (the code-space stage must have run);
    ``metrics`` is its ``sampler`` entry in bundle.json."""
    t0 = time.perf_counter()
    folder = Path(folder)
    inputs, recorded = part_inputs(
        folder, dataset, cache_dir, part="sampler", config=config, train=train_config
    )
    if recorded is not None:
        return part_report("sampler", folder, recorded)
    bundle, names = inputs.bundle, inputs.names
    train, val = (
        sampler_frames(bundle, inputs.features, inputs.latents, names[k], progress) for k in ("train", "val")
    )
    torch.manual_seed(train_config.seed)
    model = ClothSampler(config, bundle.codespace.features, int(np.prod(bundle.autoencoder.latent_shape)))
    flow_key = part_key(
        bundle,
        "sampler.safetensors",
        [config.to_dict(), train_config.flow_settings() | {"max_minutes": None}],
        splits=inputs.dataset.splits,
    )
    state = train_sampler(model, (train, val), folder / "sampler", train_config, flow_key, progress)
    model.eval()
    contact = (
        _teach_contact(model, inputs, (train, val), train_config, folder / "sampler" / "contact.pt", progress)
        if train_config.contact_steps
        else None
    )
    truth = body_frames(inputs.dataset, names["val"])
    calibration = calibrate_draws(model, bundle, (val, truth), seed=train_config.seed, progress=progress)
    regression = [m.numpy() for m in val.sequences(val.mean)]
    entry = {
        "key": inputs.key,
        "config": config.to_dict(),
        "train": asdict(train_config),
        "epochs": state["epoch"],
        "best_epoch": state["best_epoch"],
        **calibration,
        "regression_validation_mm": decoded_pve_mm(bundle, regression, truth),
        "contact": contact,
        "minutes": (time.perf_counter() - t0) / 60,
    }
    return add_trained_part(folder, "sampler", model, entry=entry)


def _teach_contact(
    model: ClothSampler, inputs, data: tuple, config: SamplerTrainSettings, path: Path, progress: bool
) -> dict:
    """The contact phase (:mod:`.sampler_contact`) on the stage's frames and their bodies, kept at
    ``path``."""
    bundle, ds = inputs.bundle, inputs.dataset
    bodies = (
        FrameDecoder(bundle.autoencoder, bundle.latent_stats),
        *(BodyContacts.of_sequences(ds, inputs.names[k]) for k in ("train", "val")),
    )

    def condition(sampler, frames, rows, gen):
        return sampler_batch(sampler, frames, rows, config.history_noise, gen)

    return teach_sampler_contact(
        model,
        data,
        bodies,
        condition=condition,
        config=config,
        shape=tuple(bundle.autoencoder.latent_shape),
        checkpoint=(path, inputs.key),
        progress=progress,
    )
