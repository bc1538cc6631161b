"""The direct-regression baseline: a recurrent network from motion to garment latents, frame by frame.

It stands in for the paper's regression peer (VirtualBones' class of methods: motion in, garment
out, no discrete codes, no retrieval) and is evaluated as mode ``direct``. A GRU reads the
standardised 124-d motion features of each frame in order (causal: frame t sees frames <= t) and an
MLP head maps its state to that frame's standardised latent (nodes x C, the mesh autoencoder's
space), which the shared decoder turns into vertices.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

from ..settings import from_settings


@dataclass(frozen=True)
class DirectSettings:
    """The direct-regression baseline's sizes."""

    hidden: int = 256  # GRU and head width
    layers: int = 2  # GRU layers
    dropout: float = 0.0  # between GRU layers

    @classmethod
    def from_dict(cls, values: dict) -> "DirectSettings":
        return from_settings(cls, values, "direct model")

    def to_dict(self) -> dict:
        return asdict(self)


class DirectRegressor(nn.Module):
    """Motion features (B, T, F) -> garment latents per frame (B, T, nodes x C): a GRU and a head."""

    def __init__(self, config: DirectSettings, features: int, latent_shape: tuple[int, int]):
        super().__init__()
        self.config, self.features, self.latent_shape = config, features, tuple(latent_shape)
        self.gru = nn.GRU(
            features,
            config.hidden,
            config.layers,
            batch_first=True,
            dropout=config.dropout if config.layers > 1 else 0.0,
        )
        self.head = nn.Sequential(
            nn.Linear(config.hidden, config.hidden),
            nn.ELU(),
            nn.Linear(config.hidden, latent_shape[0] * latent_shape[1]),
        )

    def forward(self, motion: torch.Tensor) -> torch.Tensor:
        """(B, T, F) standardised features -> (B, T, nodes * C) standardised latents."""
        states, _ = self.gru(motion)
        return self.head(states)
