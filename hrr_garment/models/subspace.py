"""The run-time decoder sized for games (:class:`SubspaceDecoder`, ``--decoder fast``): a linear
subspace of the garment's body-frame vertices (the principal components of the mesh decoder's
outputs on the training frames) and a small network from a frame's latents to its coefficients.

Why: the mesh autoencoder's decoder (:mod:`.fcmae`, run by :mod:`.inference_decoder`) applies a kernel
per vertex and layer; at 4,156 vertices a 32-character step streams 130 MB of them, most of a
crowd's frame. Here a frame costs one small MLP and one (K x 3V) product, and a crowd's frames share
the basis read (Holden et al. 2019's subspace neural physics, Unreal's ML Cloth). The FCMAE stays
for training and for what needs its latent space (the code space, the residual, the folds' base).

It is distilled from the trained model (``hrr-train`` stage ``subspace``, :mod:`hrr_garment.train.subspace`):
the basis is fitted to the full decoder's outputs and the network to their coefficients, on the
training frames' latents, so it reproduces the full decoder rather than a second model's opinion.
The network predicts the leading coefficients first and its loss is a sum over them (an orthonormal
basis), so its first K outputs are the K-component model: training fits the largest size once and
keeps the fewest components that meet the validation tolerance (bundle.json ``subspace``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

from ..settings import SettingsError, from_settings, require_number


@dataclass(frozen=True)
class SubspaceSettings:
    """The subspace decoder's sizes (``subspace.model`` in the training configuration)."""

    # basis vectors fitted; training keeps the fewest that meet the tolerance. On real-quick's dress
    # (1,046 vertices) the components alone reproduce the full decoder to 2.4 mm at 256, 0.9 at 384,
    # 0.5 at 512 (the full decoder's own error: 3.0 mm)
    max_components: int = 512
    # width of each hidden layer of the network from latents to coefficients: 512 against 1024 on
    # a 4,156-vertex model, held-out PVE the same, 7.10 against 6.78 mm on validation frames, a
    # 64-character step 0.9 ms shorter (decision 0037)
    hidden: int = 512
    layers: int = 2  # hidden layers (ELU)

    def __post_init__(self) -> None:
        for name, high in (("max_components", 4096), ("hidden", 65536), ("layers", 8)):
            require_number("subspace", name, getattr(self, name), low=1, high=high, whole=True)

    @classmethod
    def from_dict(cls, values: dict) -> "SubspaceSettings":
        return from_settings(cls, values, "subspace")

    def to_dict(self) -> dict:
        return asdict(self)


class SubspaceDecoder(nn.Module):
    """(B, N, C) latents -> (B, V, 3) body-frame vertices, as the mesh decoder's
    :meth:`~.fcmae.MeshAutoencoder.decode` gives them, through ``components`` principal components.

    Buffers: ``latent_mean``/``latent_std`` (N x C) standardise the network's input; ``mean``
    (3V) and ``basis`` (K, 3V, orthonormal rows) are the subspace; ``coeff_std`` (K) scales the
    network's outputs, each of which is trained at unit spread."""

    def __init__(
        self,
        latent_shape: tuple[int, int],
        num_vertices: int,
        components: int,
        config: SubspaceSettings = SubspaceSettings(),
    ):
        super().__init__()
        if components < 1 or components > 3 * num_vertices:
            raise SettingsError(
                f"subspace: {components} components for {num_vertices} vertices (1 .. {3 * num_vertices})"
            )
        self.config, self.latent_shape, self.num_vertices = config, tuple(latent_shape), num_vertices
        size = int(np.prod(latent_shape))
        self.register_buffer("latent_mean", torch.zeros(size))
        self.register_buffer("latent_std", torch.ones(size))
        self.register_buffer("mean", torch.zeros(3 * num_vertices))
        self.register_buffer("basis", torch.zeros(components, 3 * num_vertices))
        self.register_buffer("coeff_std", torch.ones(components))
        widths = [size] + [config.hidden] * config.layers
        layers: list[nn.Module] = []
        for a, b in zip(widths, widths[1:]):
            layers += [nn.Linear(a, b), nn.ELU()]
        self.net = nn.Sequential(*layers, nn.Linear(widths[-1], components))
        self._scaled_basis: torch.Tensor | None = None  # basis rows times their spread (inference, made once)

    def _load_from_state_dict(self, *args, **kwargs) -> None:
        self._scaled_basis = None  # made again from the weights loaded
        super()._load_from_state_dict(*args, **kwargs)

    @property
    def components(self) -> int:
        return len(self.basis)

    def coefficients(self, latents: torch.Tensor) -> torch.Tensor:
        """(B, N, C) -> (B, K) standardised coefficients (the network's raw output)."""
        x = (latents.flatten(1) - self.latent_mean) / self.latent_std
        return self.net(x)

    def vertices(self, coefficients: torch.Tensor) -> torch.Tensor:
        """(B, k) standardised coefficients, the first k <= K -> (B, V, 3) vertices through the
        first k components."""
        k = coefficients.shape[1]
        return (self.mean + (coefficients * self.coeff_std[:k]) @ self.basis[:k]).reshape(
            -1, self.num_vertices, 3
        )

    @torch.no_grad()
    def forward(self, latents: torch.Tensor) -> torch.Tensor:
        """(B, N, C) latents -> (B, V, 3) body-frame vertices (inference: no gradients)."""
        if self._scaled_basis is None or self.training or self._scaled_basis.device != self.basis.device:
            self._scaled_basis = (self.coeff_std[:, None] * self.basis).contiguous()
        c = self.coefficients(latents.to(torch.float32))
        return torch.addmm(self.mean, c, self._scaled_basis).reshape(-1, self.num_vertices, 3)

    def truncated(self, components: int) -> "SubspaceDecoder":
        """The same decoder through its first ``components`` components (a new module)."""
        if not 1 <= components <= self.components:
            raise ValueError(f"components must be in 1..{self.components}, got {components}")
        out = SubspaceDecoder(self.latent_shape, self.num_vertices, components, self.config)
        state = {k: v for k, v in self.state_dict().items()}
        last = f"net.{len(self.net) - 1}"
        for key in ("basis", "coeff_std", f"{last}.weight", f"{last}.bias"):
            state[key] = state[key][:components]
        out.load_state_dict(state)
        return out.eval()


def principal_components(
    frames: np.ndarray, count: int, chunk: int = 2048
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F, V, 3) frames -> their mean (3V), the leading ``count`` principal directions (count, 3V,
    orthonormal rows, by decreasing variance) and each one's standard deviation (count). The
    covariance is summed in float64 chunk by chunk, so memory stays at (3V)^2 whatever F is."""
    x = frames.reshape(len(frames), -1)
    if len(x) < 2:
        raise ValueError("principal components need at least two frames")
    mean = x.mean(0, dtype=np.float64)
    cov = np.zeros((x.shape[1], x.shape[1]))
    for i in range(0, len(x), chunk):
        d = x[i : i + chunk].astype(np.float64) - mean
        cov += d.T @ d
    values, vectors = np.linalg.eigh(cov / (len(x) - 1))
    order = np.argsort(values)[::-1][: min(count, x.shape[1])]
    return (
        mean.astype(np.float32),
        np.ascontiguousarray(vectors[:, order].T, np.float32),
        np.sqrt(np.maximum(values[order], 1e-20)).astype(np.float32),
    )
