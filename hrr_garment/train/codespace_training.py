"""Training the shared code space (paper 3.4): two encoders, one Gumbel-Softmax quantiser, a decoder.

Losses on a batch of windows (motion m, garment latents z, both standardised):

- reconstruction  L_rec   = mean (z - decoder(E(c_g)))^2, c_g the garment encoder's code;
- code matching   L_match = mean (E(c_g) - E(c_m))^2, c_m the motion encoder's code;
- diversity: log K - entropy of the batch-mean class distribution (both encoders), against collapse.

Curriculum: ``match_weight`` (0.1) until the validation reconstruction loss plateaus (no relative
improvement above ``plateau_delta`` for ``plateau_patience`` epochs; :class:`PlateauDetector`),
then ``match_weight_late`` (0.5). The best weights are kept by the validation loss of the
regression path (decoder(E(c_m)) against z, what inference uses); training stops early after
``patience`` epochs without improvement, but only in the last fifth of the run. Adam with weight
decay and the autoencoder's cosine learning-rate schedule over the run's progress (epochs or the
wall-clock budget, :mod:`.schedule`): a budgeted run ends at a small rate instead of stopping
with noisy weights. Gumbel temperature decays per epoch to a floor. A checkpoint after every epoch: a re-run resumes. One JSON line per epoch in
``log.jsonl``: losses, code agreement (fraction of groups where the motion and garment argmax
agree, on validation), per-group perplexity and dead classes of the garment codes, and a histogram
of the motion codes' entropies.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from ..data.windows import WindowSet
from ..models.codes import regression_embedding
from ..models.codespace import CodeSpace
from ..models.quantizer import group_entropy
from ..settings import SettingsError, from_settings
from .checkpoint import Checkpoint, EpochLog
from .loop import Budget, Epoch, EpochStep, ProgressBar, TrainingRun, fit
from .schedule import set_learning_rate

VALIDATION_PROTOCOLS = ("clips", "windows")
LATENT_LOSSES = ("standardised", "vertex")
PAPER_VALIDATION_FRACTION = 0.1  # "windows": the paper's 9:1 split of the training clips' windows


@dataclass(frozen=True)
class CodeSpaceTrainSettings:
    """The code-space stage's training settings (``codespace.train``)."""

    epochs: int = 300
    batch_size: int = 64
    learning_rate: float = 1e-3
    lr_final: float = 0.01  # cosine schedule over the run (epochs or budget) down to this x learning_rate
    weight_decay: float = 1e-4
    match_weight: float = 0.1  # stage 1
    match_weight_late: float = 0.5  # after the reconstruction plateau
    diversity: float = 0.05
    regress: float = 1.0  # weight of decoder(E(c_m)) vs z: trains the regression path directly
    temperature: float = 1.0  # Gumbel-Softmax temperature at epoch 0 ...
    temperature_decay: float = 0.98  # ... times this per epoch ...
    temperature_min: float = 0.3  # ... down to this
    plateau_patience: int = 8
    plateau_delta: float = 0.01  # relative improvement that counts as progress
    patience: int = 25  # epochs after the switch without a better validation regression loss
    max_minutes: float | None = (
        None  # a wall-clock cap on the epochs (a run it cuts short warns: pipeline.budget)
    )
    target_mm: float | None = (
        None  # validation regression error (window level) these settings reach on an idle machine
    )
    windows_per_epoch: int | None = 8192  # an epoch draws at most this many training windows (None: all)
    validation: str = "clips"  # "clips": the dataset's val split; "windows": the paper's 9:1 split of windows
    # how a latent window's error is measured: "standardised", the mean square of the standardised
    # latents; "vertex", the decoder's first-order vertex error (.vertex_metric), with vertex_ridge
    # of the former mixed in
    latent_loss: str = "standardised"
    vertex_ridge: float = 0.05
    # the contact phase after training (.contact): Adam steps on the decoder with the body's capsules
    # in the loss (0: none), the weight of the mean depth inside them (mm) beside the latent loss, and
    # how far outside the capsules that depth is counted from (metres: a clearance the decoded cloth
    # learns to keep, so that a test-time error of a few millimetres does not reach inside)
    contact_steps: int = 0
    contact_weight: float = 2.0
    contact_margin_m: float = 0.002
    seed: int = 0

    def __post_init__(self) -> None:
        if self.validation not in VALIDATION_PROTOCOLS:
            raise SettingsError(
                f"code space training: validation must be one of {', '.join(VALIDATION_PROTOCOLS)}, "
                f"got {self.validation!r}"
            )
        if self.latent_loss not in LATENT_LOSSES:
            raise SettingsError(
                f"code space training: latent_loss must be one of {', '.join(LATENT_LOSSES)}, "
                f"got {self.latent_loss!r}"
            )
        if self.contact_steps < 0 or self.contact_weight < 0:
            raise SettingsError(
                f"code space training: contact_steps and contact_weight must be at least 0, got "
                f"{self.contact_steps} and {self.contact_weight}"
            )
        if not 0.0 <= self.contact_margin_m <= 0.05:
            raise SettingsError(
                f"code space training: contact_margin_m must be in [0, 0.05] metres, got {self.contact_margin_m}"
            )
        if not 0.0 <= self.vertex_ridge <= 1.0:
            raise SettingsError(
                f"code space training: vertex_ridge must be in [0, 1], got {self.vertex_ridge}"
            )

    @classmethod
    def from_dict(cls, values: dict) -> "CodeSpaceTrainSettings":
        return from_settings(cls, values, "code space training")


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


@dataclass
class WindowTensors:
    """Standardised motion and latent windows as tensors, each frame stored once: window i is
    rows ``first[i] .. first[i] + window - 1`` of both (the real-motion library's training windows
    would take 3.6 GB as windows; :class:`~hrr_garment.data.windows.WindowFrames`)."""

    motion: torch.Tensor  # (frames, F) standardised
    latents: torch.Tensor  # (frames, nodes, C) standardised
    first: torch.Tensor  # (N,) int64
    window: int

    @classmethod
    def of(cls, windows: WindowSet, motion_stats, latent_stats) -> "WindowTensors":
        if not np.array_equal(windows.motion.first, windows.latents.first):
            raise ValueError("the motion and latent windows are not read from the same frames")
        lat = windows.latents.frames
        lat = latent_stats.normalize(lat.reshape(len(lat), -1)).reshape(lat.shape)
        return cls(
            torch.from_numpy(motion_stats.normalize(windows.motion.frames)),
            torch.from_numpy(lat),
            torch.from_numpy(windows.motion.first),
            windows.motion.window,
        )

    def __len__(self) -> int:
        return len(self.first)

    def frame_rows(self, rows) -> torch.Tensor:
        """(n, W) the stored frames of the windows ``rows`` (a slice or indices)."""
        return self.first[rows].unsqueeze(-1) + torch.arange(self.window)

    def __getitem__(self, rows) -> tuple[torch.Tensor, torch.Tensor]:
        """The windows ``rows`` (a slice or indices): motion (n, W, F) and latents (n, W, nodes, C)."""
        frames = self.frame_rows(rows)
        return self.motion[frames], self.latents[frames]


def mean_square(error: torch.Tensor) -> torch.Tensor:
    """The mean square of standardised latent errors: the code space's default latent loss."""
    return error.pow(2).mean()


def _losses(
    model: CodeSpace,
    motion: torch.Tensor,
    latents: torch.Tensor,
    temperature: float,
    latent_loss: Callable[[torch.Tensor], torch.Tensor] = mean_square,
) -> dict[str, torch.Tensor]:
    q, body = model.quantizer, model.body_of(motion)
    g_logits, m_logits = model.garment_encoder(latents, body), model.motion_encoder(motion)
    _, e_g = q(g_logits, temperature)
    _, e_m = q(m_logits, temperature)
    # the regression path as inference runs it: the code distribution's mean embedding (or the
    # sampled code's, for the paper's argmax regression)
    e_reg = (
        regression_embedding(model, q.split(m_logits)) if model.config.regression_code == "expected" else e_m
    )
    return {
        "rec": latent_loss(model.decode(e_g, body=body) - latents),
        "match": (e_g - e_m).pow(2).mean(),
        "diversity": 0.5 * (q.diversity_loss(g_logits) + q.diversity_loss(m_logits)),
        "g_logits": g_logits.detach(),
        "m_logits": m_logits.detach(),
        "regress": latent_loss(model.decode(e_reg, body=body) - latents),
    }


@torch.no_grad()
def evaluate(
    model: CodeSpace,
    data: WindowTensors,
    batch: int = 256,
    latent_loss: Callable[[torch.Tensor], torch.Tensor] = mean_square,
) -> dict:
    """Validation losses (the latent errors measured by ``latent_loss``) and code statistics (eval
    mode: argmax codes)."""
    model.eval()
    sums = {"rec": 0.0, "match": 0.0, "regress": 0.0}
    agree, entropies, g_idx = 0.0, [], []
    for i in range(0, len(data), batch):
        out = _losses(model, *data[i : i + batch], 1.0, latent_loss)
        n = len(out["g_logits"])
        for k in sums:
            sums[k] += float(out[k]) * n
        gi = model.quantizer.split(out["g_logits"]).argmax(-1)
        mi = model.quantizer.split(out["m_logits"]).argmax(-1)
        agree += float((gi == mi).float().mean(1).sum())
        entropies.append(group_entropy(model.quantizer.split(out["m_logits"])))
        g_idx.append(gi)
    n = max(1, len(data))
    ent = torch.cat(entropies) if entropies else torch.zeros(0)
    usage = model.quantizer.usage(torch.cat(g_idx)) if g_idx else None
    hist = np.histogram(ent.numpy(), bins=10, range=(0.0, math.log(model.quantizer.classes)))[0].tolist()
    return {
        **{k: v / n for k, v in sums.items()},
        "agreement": agree / n,
        "entropy_mean": float(ent.mean()) if len(ent) else float("nan"),
        "entropy_histogram": hist,
        "dead_classes": usage.dead if usage else 0,
        "perplexity": usage.perplexity if usage else float("nan"),
    }


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
    out = _losses(model, *batch, temperature, latent_loss)
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
            Checkpoint(folder / "checkpoint.pt", key, optimizer=optimizer, plateau=plateau),
            EpochLog(folder / "log.jsonl"),
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
