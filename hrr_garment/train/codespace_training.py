"""Training the shared code space (paper 3.4): two encoders, one Gumbel-Softmax quantiser, a decoder.

Losses on a batch of windows (motion m, garment latents z, both standardised):

- reconstruction  L_rec   = mean (z - decoder(E(c_g)))^2, c_g the garment encoder's code;
- code matching   L_match = mean (E(c_g) - E(c_m))^2, c_m the motion encoder's code;
- diversity: log K - entropy of the batch-mean class distribution (both encoders), against collapse.

Curriculum: ``match_weight`` (0.1) until the validation reconstruction loss plateaus (no relative
improvement above ``plateau_delta`` for ``plateau_patience`` epochs; :class:`PlateauDetector`), then
``match_weight_late`` (0.5). The best weights are kept by the validation loss of the regression path
(decoder(E(c_m)) against z, what inference uses); training stops early after ``patience`` epochs
without improvement, but only in the last fifth of the run. Adam with weight decay and the
autoencoder's cosine learning-rate schedule over the run's progress (epochs or the wall-clock
budget, :mod:`.schedule`): a budgeted run ends at a small rate instead of stopping with noisy
weights. Gumbel temperature decays per epoch to a floor. A checkpoint after every epoch: a re-run
resumes. One JSON line per epoch in ``log.jsonl``: losses, code agreement (fraction of groups where
the motion and garment argmax agree, on validation), per-group perplexity and dead classes of the
garment codes, and a histogram of the motion codes' entropies. The settings are in
:mod:`.codespace_settings`, the losses and the validation in :mod:`.codespace_losses`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import torch

from ..models.codespace import CodeSpace
from .checkpoint import Checkpoint, EpochLog
from .codespace_losses import WindowTensors, batch_losses, evaluate, mean_square
from .codespace_settings import CodeSpaceTrainSettings
from .loop import Budget, Epoch, EpochStep, ProgressBar, TrainingRun, fit
from .schedule import set_learning_rate


class PlateauDetector:
    """Says once that a loss has plateaued: ``patience`` updates in a row without a relative
    improvement of more than ``delta`` over the best value seen."""

    def __init__(self, patience: int, delta: float):
        self.patience, self.delta = patience, delta
        self.best, self.stale, self.fired = math.inf, 0, False

    def update(self, value: float) -> bool:
        if self.fired:
            return False
        if value < self.best * (1.0 - self.delta):
            self.best, self.stale = value, 0
        else:
            self.best = min(self.best, value)
            self.stale += 1
        self.fired = self.stale >= self.patience
        return self.fired

    def state_dict(self) -> dict:
        return {"best": self.best, "stale": self.stale, "fired": self.fired}

    def load_state_dict(self, state: dict) -> None:
        self.best, self.stale, self.fired = float(state["best"]), int(state["stale"]), bool(state["fired"])


def _train_step(
    model: CodeSpace,
    optimizer: torch.optim.Optimizer,
    batch: tuple,
    config: CodeSpaceTrainSettings,
    *,
    weights: tuple[float, float],
    latent_loss: Callable[[torch.Tensor], torch.Tensor],
) -> dict:
    """One optimiser step on a batch of windows at this epoch's (temperature, match weight);
    returns its losses."""
    temperature, match_weight = weights
    out = batch_losses(model, *batch, temperature=temperature, latent_loss=latent_loss)
    loss = out["rec"] + match_weight * out["match"] + config.diversity * out["diversity"]
    if config.regress:
        loss = loss + config.regress * out["regress"]
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    optimizer.step()
    return out


class _CodeSpaceEpochs(EpochStep):
    """The code space's epoch: the temperature and match weight of its stage of the curriculum, a
    fresh sample of training windows in batches (the cosine rate set before each), the validation
    losses, then the plateau detector's switch."""

    def __init__(
        self,
        model: CodeSpace,
        optimizer: torch.optim.Optimizer,
        data: tuple[WindowTensors, WindowTensors],
        config: CodeSpaceTrainSettings,
        plateau: PlateauDetector,
        latent_loss: Callable[[torch.Tensor], torch.Tensor],
    ):
        self.model, self.optimizer, self.config, self.plateau = model, optimizer, config, plateau
        (self.train, self.val), self.latent_loss = data, latent_loss

    def start(self, run: TrainingRun) -> None:
        # one generator for the run (not one an epoch as the fast decoder's), seeded at the epoch resumed
        self.gen = torch.Generator().manual_seed(self.config.seed + run.state["epoch"])

    def run_epoch(self, run: TrainingRun) -> Epoch:
        model, config, state, epoch = self.model, self.config, run.state, run.state["epoch"]
        temperature = max(config.temperature_min, config.temperature * config.temperature_decay**epoch)
        match_weight = config.match_weight if state["switched_at"] is None else config.match_weight_late
        model.train()
        # bounded epochs: the temperature, the plateau switch and the patience count epochs, and
        # the real-motion library has some 100,000 windows; each epoch draws a fresh sample
        order = torch.randperm(len(self.train), generator=self.gen)[: config.windows_per_epoch]
        sums = {"rec": 0.0, "match": 0.0, "diversity": 0.0}
        for i in range(0, len(order), config.batch_size):
            set_learning_rate(self.optimizer, config, run.progress(epoch + i / len(order)))
            idx = order[i : i + config.batch_size]
            out = _train_step(
                model,
                self.optimizer,
                self.train[idx],
                config,
                weights=(temperature, match_weight),
                latent_loss=self.latent_loss,
            )
            for k in sums:
                sums[k] += out[k].item() * len(idx)
        metrics = evaluate(model, self.val, latent_loss=self.latent_loss)
        if state["switched_at"] is None and self.plateau.update(metrics["rec"]):
            state["switched_at"] = epoch + 1  # the epochs done, this one counted
        log = {
            "temperature": temperature,
            "match_weight": match_weight,
            "learning_rate": self.optimizer.param_groups[0]["lr"],
            **{f"train_{k}": v / len(order) for k, v in sums.items()},
            **{f"val_{k}": v for k, v in metrics.items()},
        }
        postfix = {
            "rec": f"{metrics['rec']:.3f}",
            "regress": f"{metrics['regress']:.3f}",
            "agree": f"{metrics['agreement']:.2f}",
            "stage": 1 if state["switched_at"] is None else 2,
        }
        # the best regression path (what inference uses) is kept in both stages: a budgeted run
        # on a large library can end before the plateau switch (real-quick: 17 epochs, no switch)
        return Epoch(metrics["regress"], log, postfix)


def train_codespace(
    model: CodeSpace,
    train: WindowTensors,
    val: WindowTensors,
    folder: Path,
    config: CodeSpaceTrainSettings = CodeSpaceTrainSettings(),
    key: str = "",
    progress: bool = True,
    latent_loss: Callable[[torch.Tensor], torch.Tensor] = mean_square,
) -> dict:
    """Train (or resume) in ``folder``; leaves the best weights in ``model`` and returns a summary.
    ``latent_loss`` measures the latent windows' errors (:class:`.vertex_metric.VertexMetric` for
    ``config.latent_loss`` "vertex")."""
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(config.seed)
    optimizer = torch.optim.Adam(
        model.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
    )
    plateau = PlateauDetector(config.plateau_patience, config.plateau_delta)
    t0 = time.perf_counter()
    state = fit(
        model,
        _CodeSpaceEpochs(model, optimizer, (train, val), config, plateau, latent_loss),
        Budget(config.epochs, config.max_minutes, patience=config.patience),
        callbacks=[
            EpochLog(folder / "log.jsonl"),
            Checkpoint(folder / "checkpoint.pt", key, optimizer=optimizer, plateau=plateau),
            ProgressBar("code space", progress),
        ],
        state={"switched_at": None},
    )
    return {
        **state,
        "minutes": (time.perf_counter() - t0) / 60,
        "final": evaluate(model, val, latent_loss=latent_loss),
        "config": asdict(config),
    }
