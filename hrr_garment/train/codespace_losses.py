"""The code space's losses on a batch of windows (reconstruction, code matching, diversity, the
regression path) and its validation (:func:`evaluate`: the losses and code statistics), on the
windows stored as tensors (:class:`WindowTensors`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from ..data.windows import WindowSet
from ..models.codes import regression_embedding
from ..models.codespace import CodeSpace
from ..models.quantizer import group_entropy


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


def batch_losses(
    model: CodeSpace,
    motion: torch.Tensor,
    latents: torch.Tensor,
    temperature: float,
    latent_loss: Callable[[torch.Tensor], torch.Tensor] = mean_square,
) -> dict[str, torch.Tensor]:
    """The losses of a batch of windows at the Gumbel ``temperature``, with both encoders' logits
    (detached: the code statistics' input)."""
    q, condition = model.quantizer, model.condition_of(motion)
    g_logits, m_logits = model.garment_encoder(latents, condition), model.motion_encoder(motion)
    _, e_g = q(g_logits, temperature)
    _, e_m = q(m_logits, temperature)
    # the regression path as inference runs it: the code distribution's mean embedding (or the
    # sampled code's, for the paper's argmax regression)
    e_reg = (
        regression_embedding(model, q.split(m_logits)) if model.config.regression_code == "expected" else e_m
    )
    return {
        "rec": latent_loss(model.decode(e_g, condition=condition) - latents),
        "match": (e_g - e_m).pow(2).mean(),
        "diversity": 0.5 * (q.diversity_loss(g_logits) + q.diversity_loss(m_logits)),
        "g_logits": g_logits.detach(),
        "m_logits": m_logits.detach(),
        "regress": latent_loss(model.decode(e_reg, condition=condition) - latents),
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
        out = batch_losses(model, *data[i : i + batch], 1.0, latent_loss)
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
