"""The code space's losses measured in vertices: a metric on standardised latents from the decoder.

The code space reconstructs standardised latents (each node's channel to unit variance over the
training frames), and a mean square error there weighs every latent value alike. What a user sees,
and what PVE measures, is vertices, and the latents differ in how far they move them: a hem node
swings the hem, a waist node barely moves the cloth, yet both are unit variance once standardised.
So the loss can be the vertex error to first order instead: with J the autoencoder decoder's
Jacobian with respect to the standardised latents (3V x D, D = nodes x channels), an error e in a
frame's latents moves the vertices by J e, whose squared length is e^T (J^T J) e. The metric is
J^T J averaged over training frames, scaled to trace D so that an error of the same size on every
latent scores as the mean square error did, and mixed with a little of the identity (``ridge``)
so that no latent goes unlearnt where the decoder is locally flat.

The Jacobian is taken by central differences through the decoder (a batch of 2D decodes a frame)
on a sample of training frames. The metric is kept as a factor F (D x k,
the eigenvectors that hold all but 1e-4 of its trace, scaled by the roots of their eigenvalues),
so the loss of a batch of errors E (n x D) is ``(1 - ridge) |E F|^2 / D + ridge |E|^2 / D``.
"""

from __future__ import annotations

import numpy as np
import torch
from tqdm.auto import tqdm

from ..models.fcmae import MeshAutoencoder

TRACE_KEPT = 1.0 - 1e-4  # the metric's eigenvectors kept: all but this share of its trace
SAMPLE_FRAMES = 16  # training frames the metric averages (2 x D decodes each; the diagonal of 16 and of 32
#                     seeded samples correlate to 0.999 on real-quick)


def sample_frames(frames: np.ndarray, count: int = SAMPLE_FRAMES, seed: int = 0) -> np.ndarray:
    """``count`` of ``frames`` (n, ...) drawn without replacement, seeded (all of them when fewer)."""
    if len(frames) <= count:
        return frames
    return frames[np.sort(np.random.default_rng(seed).choice(len(frames), count, replace=False))]


class VertexMetric:
    """The first-order squared vertex error of standardised latent errors, scaled so that an
    isotropic unit error scores 1 a value (see the module docstring)."""

    def __init__(self, factor: torch.Tensor, ridge: float):
        if not 0.0 <= ridge <= 1.0:
            raise ValueError(f"ridge must be in [0, 1], got {ridge}")
        self.factor, self.ridge = factor.float(), float(ridge)

    @classmethod
    def of_decoder(
        cls,
        autoencoder: MeshAutoencoder,
        frames: np.ndarray,
        std: np.ndarray,
        ridge: float = 0.05,
        step: float = 1e-2,
        progress: bool = True,
    ) -> "VertexMetric":
        """From ``frames`` (n, nodes, C) raw latents of training frames and the latents' per-value
        standard deviations ``std`` (nodes x C,) that standardise them; ``step`` is the central
        differences' step in standardised units (the decoder is smooth on that scale, and float32
        rounding stays far below it)."""
        nodes, channels = frames.shape[1:]
        size = nodes * channels
        scale = (
            torch.as_tensor(np.asarray(std, np.float32).reshape(size)) * step
        )  # a standardised step, in raw units
        directions = torch.diag(scale).reshape(size, nodes, channels)
        metric = torch.zeros(size, size, dtype=torch.float64)
        with torch.no_grad():
            for z in tqdm(
                torch.as_tensor(np.asarray(frames, np.float32)),
                desc="vertex metric",
                unit="frame",
                disable=not progress,
            ):
                jacobian = []
                for chunk in directions.split(128):
                    moved = autoencoder.decode(torch.cat([z + chunk, z - chunk])).double()
                    jacobian.append(
                        ((moved[: len(chunk)] - moved[len(chunk) :]) / (2 * step)).reshape(len(chunk), -1)
                    )
                jacobian = torch.cat(jacobian)  # (D, 3V): row d is the vertices' motion per unit of latent d
                metric += jacobian @ jacobian.T
        metric = metric * (size / torch.trace(metric))
        values, vectors = torch.linalg.eigh(metric)
        values, vectors = values.flip(0).clamp(min=0.0), vectors.flip(1)
        kept = int(torch.searchsorted(torch.cumsum(values, 0) / values.sum(), TRACE_KEPT)) + 1
        return cls(vectors[:, :kept] * values[:kept].sqrt(), ridge)

    @property
    def size(self) -> int:
        return self.factor.shape[0]

    def __call__(self, error: torch.Tensor) -> torch.Tensor:
        """The mean loss of ``error`` (..., D) or (..., nodes, C), standardised latents."""
        flat = error.reshape(-1, self.size)
        weighted = (flat @ self.factor).pow(2).sum(1).mean() / self.size
        return (1.0 - self.ridge) * weighted + self.ridge * flat.pow(2).mean()
