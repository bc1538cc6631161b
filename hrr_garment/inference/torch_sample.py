"""The sample mode's draw as a stage of the torch step (:mod:`.torch_step`), for a graph to hold.

:meth:`~.frame_path.FramePath.draw` for one frame of N characters, each character's draw state
explicit, as the step's window state is: the two noise filters (``drive``, ``noise``) and the
regression's standardised latents of the frame before (``latents``). The white noise comes in: a
graph holds no random generator, so the engine draws it, two N(0, I) vectors per character and frame
(:func:`~hrr_garment.models.sampler.white_noise` says which; the second is read at a character's
first frame only). Fed what a character's seeded generator draws, the stage draws what the Python
stream draws for that seed.
"""

from __future__ import annotations

import torch
from torch import nn

from ..models.sampler import ClothSampler, continue_noise, start_noise


class SampleStage(nn.Module):
    """Standardised features (N, F) and the regression's standardised latents (N, L) of a frame ->
    the drawn standardised latents (N, L) and the draw state one frame on."""

    def __init__(self, sampler: ClothSampler, steps: int):
        super().__init__()
        if sampler.config.history:
            raise ValueError(
                "a graph draws without the frames drawn before (the sampler's history must be 0, "
                f"this one's is {sampler.config.history})"
            )
        self.sampler, self.steps = sampler.eval(), int(steps)

    @property
    def size(self) -> int:
        """L, the latent values a frame draws (the noise's and each state's width)."""
        return self.sampler.latent_size

    def forward(
        self,
        features: torch.Tensor,
        mean: torch.Tensor,
        first: torch.Tensor,
        white: torch.Tensor,
        drive: torch.Tensor,
        noise: torch.Tensor,
        previous: torch.Tensor,
    ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """``first`` (N, 1) true at a character's first frame, ``white`` (N, 2, L) its white noise,
        and its state: the filters' ``drive`` and ``noise`` and the latents of the frame before
        (``previous``), each (N, L). The state comes back in that order."""
        decay = self.sampler.noise_decay
        started = start_noise(decay, white[:, 0], white[:, 1])
        carried = continue_noise(decay, white[:, 0], (drive, noise))
        drive = torch.where(first, started[0], carried[0])
        noise = torch.where(first, started[1], carried[1])
        previous = torch.where(first, mean, previous)
        context = self.sampler.context(features, mean, previous)
        scaled = self.sampler.draw(context, self.sampler.temperature * noise, self.steps)
        return mean + scaled * self.sampler.residual_scale, (drive, noise, mean)
