"""Fully convolutional mesh autoencoder with spatially varying kernels (FCMAE, Zhou et al. 2020).

Every layer is one :class:`~.fcmae_layers.VcConv`: each output vertex has its own neighbour list
(a 1-ring on the same level, a pooling neighbourhood when going down, the transposed one going up),
and its kernel for neighbour slot s is ``sum_m coeff[v, s, m] * W_m`` over M shared basis kernels.
A :class:`~.fcmae_layers.Block` adds a residual path (a learned, normalised neighbour average when
the vertex count changes, a 1x1 map when the channel count changes) as
``sqrt(1 - r) * conv + sqrt(r) * residual``.

The encoder maps (B, V, 3) vertex offsets from the template (in the body's heading frame, scaled
by the training data's spread) to (B, N, 8) latents on the coarsest level; the decoder maps back.
Tensors are vertex-major inside, (V, B, C): a gather then picks whole rows of B x C values, which
keeps it (and its backward, an index_add) fast on the CPU; each layer is one batched matmul of
(V, B, S * C_in) by per-vertex kernels (V, S * C_in, C_out). ``inference_decoder()`` precomputes those
kernels for inference (:mod:`.inference_decoder`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from ..settings import SettingsError, from_settings, require_number
from .fcmae_layers import Block
from .hierarchy import Hierarchy

if TYPE_CHECKING:
    from .inference_decoder import InferenceDecoder


@dataclass(frozen=True)
class AutoencoderSettings:
    """The mesh autoencoder's layer widths, basis size and sampling hierarchy settings."""

    channels: tuple[int, ...] = (16, 32, 64, 128)  # per level; the last value repeats for deeper levels
    latent_channels: int = 8
    basis: int = 17
    residual: float = 0.5
    latent_fraction: float = 0.01
    min_latent_nodes: int = (
        4  # configs/train.yaml asks 64; 4 keeps models trained before it loading as they were
    )
    stride: int = 2
    radius: int = 2

    def __post_init__(self) -> None:
        what = "autoencoder"
        if not isinstance(self.channels, (tuple, list)) or not self.channels:
            raise SettingsError(f"{what}: channels must be a list of widths, got {self.channels!r}")
        for width in self.channels:
            require_number(what, "channels", width, low=1, high=4096, whole=True)
        for name, high in (
            ("latent_channels", 512),
            ("basis", 256),
            ("min_latent_nodes", 100_000),
            ("stride", 16),
            ("radius", 16),
        ):
            require_number(what, name, getattr(self, name), low=1, high=high, whole=True)
        require_number(what, "residual", self.residual, low=0, high=1)
        require_number(what, "latent_fraction", self.latent_fraction, low=0, high=1, above=True)

    @classmethod
    def from_dict(cls, values: dict) -> "AutoencoderSettings":
        if "channels" in values:
            values = {**values, "channels": tuple(values["channels"])}
        return from_settings(cls, values, "autoencoder")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["channels"] = list(self.channels)
        return d

    def hierarchy_options(self) -> dict:
        """The keyword arguments of :func:`~hrr_garment.models.hierarchy.build_hierarchy` this model uses."""
        return {
            "latent_fraction": self.latent_fraction,
            "min_latent_nodes": self.min_latent_nodes,
            "stride": self.stride,
            "radius": self.radius,
        }

    def channel(self, level: int) -> int:
        return self.channels[min(level, len(self.channels) - 1)]


def vertex_distance(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """(..., V, 3) -> (..., V): Euclidean distance per vertex; a 1 micrometre floor keeps its
    gradient finite where the two meet."""
    return ((a - b).square().sum(-1) + 1e-12).sqrt()


class MeshAutoencoder(nn.Module):
    """FCMAE for one template. ``template`` (V, 3) and the data scale define the input normalisation."""

    def __init__(
        self,
        hierarchy: Hierarchy,
        config: AutoencoderSettings = AutoencoderSettings(),
        template: np.ndarray | None = None,
        scale: float = 0.1,
    ):
        super().__init__()
        self.config, self.hierarchy = config, hierarchy
        levels, c = hierarchy.levels, config
        self.register_buffer(
            "template",
            torch.as_tensor(
                np.zeros((hierarchy.sizes[0], 3)) if template is None else template, dtype=torch.float32
            ),
        )
        self.register_buffer("scale", torch.tensor(float(scale)))
        enc = [Block(hierarchy.conv[0], None, (3, c.channel(0)), basis=c.basis, residual=c.residual)]
        for level in range(levels - 1):
            enc.append(
                Block(
                    hierarchy.down[level],
                    hierarchy.down[level],
                    (c.channel(level), c.channel(level + 1)),
                    basis=c.basis,
                    residual=c.residual,
                )
            )
        enc.append(
            Block(
                hierarchy.conv[-1],
                None,
                (c.channel(levels - 1), c.latent_channels),
                basis=c.basis,
                residual=c.residual,
                activation=False,
            )
        )
        dec = [
            Block(
                hierarchy.conv[-1],
                None,
                (c.latent_channels, c.channel(levels - 1)),
                basis=c.basis,
                residual=c.residual,
            )
        ]
        for level in reversed(range(levels - 1)):
            dec.append(
                Block(
                    hierarchy.up[level],
                    hierarchy.up[level],
                    (c.channel(level + 1), c.channel(level)),
                    basis=c.basis,
                    residual=c.residual,
                )
            )
        dec.append(
            Block(
                hierarchy.conv[0],
                None,
                (c.channel(0), 3),
                basis=c.basis,
                residual=c.residual,
                activation=False,
            )
        )
        self.encoder, self.decoder = nn.Sequential(*enc), nn.Sequential(*dec)

    @property
    def latent_shape(self) -> tuple[int, int]:
        return self.hierarchy.sizes[-1], self.config.latent_channels

    def encode(self, vertices: torch.Tensor) -> torch.Tensor:
        """(B, V, 3) heading-frame vertices -> (B, N, 8) latents."""
        x = ((vertices - self.template) / self.scale).transpose(0, 1)  # vertex-major inside
        return self.encoder(x).transpose(0, 1)

    def decode(self, latents: torch.Tensor) -> torch.Tensor:
        """(B, N, 8) latents -> (B, V, 3) heading-frame vertices."""
        return self.decoder(latents.transpose(0, 1)).transpose(0, 1) * self.scale + self.template

    def forward(self, vertices: torch.Tensor) -> torch.Tensor:
        return self.decode(self.encode(vertices))

    def fit_latents(
        self, vertices: torch.Tensor, steps: int = 10, lr: float = 0.03, batch: int = 32
    ) -> torch.Tensor:
        """(B, V, 3) -> (B, N, 8): the encoder's latents refined by ``steps`` Adam steps on each
        frame's mean per-vertex distance through the decoder (the weights stay fixed). That is
        the error metric itself: on the quick dress it ends 0.1 mm lower than the training loss's
        L1 per coordinate in the same 10 steps (docs/benchmarks.md).

        Only the decoder runs at inference; the encoder just turns the dataset into latents for
        the code space, and on frames it has not seen it lands short of the latent the decoder
        needs (quick dress: 10 steps take held-out errors from 6.58 / 6.01 to 5.88 / 5.38 mm,
        docs/autoencoder.md). Each frame's loss is its own mean, summed over the batch, so a
        frame gets the same latent whatever batch it is in."""
        out = []
        for i in range(0, len(vertices), batch):
            x = vertices[i : i + batch]
            with torch.no_grad():
                z = self.encode(x)
            if steps > 0:
                z.requires_grad_(True)
                optimizer = torch.optim.Adam([z], lr=lr)
                with torch.enable_grad():
                    for _ in range(steps):
                        loss = vertex_distance(self.decode(z), x).mean(1).sum()
                        (z.grad,) = torch.autograd.grad(loss, z)  # latents only: no weight gradients
                        optimizer.step()
            out.append(z.detach())
        return torch.cat(out) if out else torch.zeros(0, *self.latent_shape)

    def inference_decoder(self, native: bool | None = None, precision: str = "float32") -> "InferenceDecoder":
        """The inference-only form of :attr:`decoder` (:mod:`.inference_decoder`)."""
        from .inference_decoder import InferenceDecoder

        return InferenceDecoder(self, native, precision=precision)
