"""The settling lag after a stop (:mod:`.settle`) as a torch stage of the streaming step: each
character's last lagged latents and stillness clock carried as one state row (the latents
flattened, the clock's reading last), the same recursion as :func:`.settle.settle_crowd` in
float32."""

from __future__ import annotations

import torch
from torch import nn

from ..motion.memory import LONG_STILL_S
from .settle import FADE
from .torch_features import FeatureStage, advanced_clock


class SettleStage(nn.Module):
    """The lag at ``seconds`` and ``fps``; ``forward`` takes a frame's latents (N, nodes, C), its
    features (N, F), the state (N, nodes C + 1) and whether each character starts here (N,) bool,
    and gives the lagged latents and the next state."""

    def __init__(self, seconds: float, fps: float):
        super().__init__()
        self.seconds, self.fps = float(seconds), float(fps)

    def forward(
        self, latents: torch.Tensor, features: torch.Tensor, state: torch.Tensor, first: torch.Tensor
    ):
        n = latents.shape[0]
        speed, still = FeatureStage.speed_and_still(features)  # (N, 1, 1)
        # the stillness clock one frame on (motion.memory.clock_step), LONG_STILL_S at a start
        tau = advanced_clock(state[:, -1:].reshape(n, 1, 1), speed, still, fps=self.fps)
        start = first.reshape(n, 1, 1)
        tau = torch.where(start, torch.full_like(tau, LONG_STILL_S), tau)
        lag = self.seconds * torch.clamp(1.0 - tau / (FADE * self.seconds), 0.0, 1.0)
        keep = still * torch.exp(-1.0 / (self.fps * torch.clamp(lag, min=1e-6)))
        keep = torch.where(start | (lag <= 0), torch.zeros_like(keep), keep)
        out = keep * state[:, :-1].reshape(latents.shape) + (1.0 - keep) * latents
        return out, torch.cat([out.reshape(n, -1), tau.reshape(n, 1)], 1)
