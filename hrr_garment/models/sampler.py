"""The generative decoder (mode ``sample``): draws a frame's cloth from the simulator's distribution
instead of its conditional mean.

Loose cloth is chaotic: simulations one part in 10,000 apart end 15-25 mm apart, so a regression
learns their mean, which no simulation looks like (blurred folds, a damped hem). The sampler draws
what the regression averages away: frame t's *departure* from the regression's (causal) latents,
in the autoencoder's latent space, given the regression's latents of frame t, their change since
t-1 and the frame's standardised motion features (velocities the mean may hide). It is a flow
matching model: a velocity field carries Gaussian noise to the departure in a few Euler steps, so
the departure is a smooth function of the condition and the noise. Departures are scaled per
latent value by their training spread (``residual_scale``) so the noise and the target have
comparable sizes.

Temporal coherence comes from the noise: each character's noise moves from frame to frame as
smoothed white noise (:meth:`SampleTrack.next_noise`), so every frame is a draw of its own
condition's distribution and consecutive frames are near each other, as the cloth's state carries
on. The noise's pole ``noise_decay`` (how fast it moves) and its scale ``temperature`` (how wide a
draw is: a flow that does not fully separate what the condition decides from what chaos decides
draws too wide a cloth) are calibrated on the validation clips
(:mod:`hrr_garment.train.sampler_calibration`). Frames are drawn causally from a seeded generator,
so a stream and an offline clip draw the same frame from the same seed.

Two ways measured and left (docs/sampler.md): conditioning each frame on the departures drawn for
the frames before (teacher-forced in training) drifts in a roll-out, 4-6 x the trained spread
within a second (a seeded draw of real-motion validation clips 199 mm from their simulation against
the regression's 50 mm); drawing the departure's change since the frame before integrates into a
random walk (183 mm).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from ..settings import from_settings

# each size's bounds (a bundle's settings are read from outside)
SIZE_BOUNDS = {
    "hidden": (1, 8192),
    "layers": (1, 32),
    "history": (0, 16),
    "steps": (1, 64),
    "time_features": (1, 1024),
}


@dataclass(frozen=True)
class SamplerSettings:
    """The sampler's sizes and its default integration."""

    hidden: int = 512  # the velocity network's width
    layers: int = 3  # its hidden layers after the first
    history: int = 0  # previous frames' drawn departures each frame is also given (0: none; drifts)
    steps: int = 1  # Euler steps from noise to a departure at run time (network evaluations a frame)
    time_features: int = 32  # sinusoidal features of the flow's time

    @classmethod
    def from_dict(cls, values: dict) -> "SamplerSettings":
        """The settings of ``values`` (a training config's, or a bundle's: read from outside, so every
        size is a whole number within bounds before a network is built of it)."""
        settings = from_settings(cls, values, "sampler model")
        for name, (low, high) in SIZE_BOUNDS.items():
            value = getattr(settings, name)
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise ValueError(
                    f"sampler model: {name} must be a whole number in [{low}, {high}], got {value!r}"
                )
        return settings

    def to_dict(self) -> dict:
        return asdict(self)


def time_features(tau: torch.Tensor, count: int) -> torch.Tensor:
    """(B,) flow times in [0, 1] -> (B, count) sines and cosines of geometric frequencies."""
    half = count // 2
    freqs = torch.exp(torch.arange(half, dtype=tau.dtype) * (-math.log(1000.0) / max(half - 1, 1)))
    angles = tau[:, None] * freqs[None] * 1000.0
    out = torch.cat([torch.sin(angles), torch.cos(angles)], -1)
    return out if out.shape[1] == count else torch.cat([out, torch.zeros_like(tau)[:, None]], -1)


class ClothSampler(nn.Module):
    """A frame's departure from the regression, drawn given its condition (module docstring).

    ``features``: the model's per-frame motion features (F); ``latent_size``: nodes x C."""

    def __init__(self, config: SamplerSettings, features: int, latent_size: int):
        super().__init__()
        self.config, self.features, self.latent_size = config, features, latent_size
        h = config.hidden
        self.condition_size = features + latent_size * (2 + config.history)
        self.condition = nn.Linear(self.condition_size, h)
        self.state = nn.Linear(latent_size, h, bias=False)
        self.time = nn.Linear(config.time_features, h, bias=False)
        blocks: list[nn.Module] = []
        for _ in range(config.layers):
            blocks += [nn.SiLU(), nn.Linear(h, h)]
        self.body = nn.Sequential(*blocks, nn.SiLU(), nn.Linear(h, latent_size))
        # set by training: the departures' spread per latent value (standardised latents), the
        # pole of the noise's filter in time and the noise's scale
        self.register_buffer("residual_scale", torch.ones(latent_size))
        self.register_buffer("noise_decay", torch.zeros(()))
        self.register_buffer("temperature", torch.ones(()))  # the noise's scale (a draw's spread)

    def context(
        self,
        features: torch.Tensor,
        mean: torch.Tensor,
        previous_mean: torch.Tensor,
        history: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """The condition's part of the first layer, (B, hidden), made once per frame: ``features``
        (B, F) standardised, ``mean`` and ``previous_mean`` (B, L) the regression's standardised
        latents at t and t-1, ``history`` (B, history, L) the scaled departures drawn at t-1, t-2, ...
        (None where the sampler takes none)."""
        parts = [features, mean, mean - previous_mean]
        if self.config.history:
            parts.append(history.reshape(len(history), -1))
        return self.condition(torch.cat(parts, -1))

    def velocity(self, x: torch.Tensor, tau: torch.Tensor, context: torch.Tensor) -> torch.Tensor:
        """The flow's velocity at scaled departures ``x`` (B, L) and times ``tau`` (B,)."""
        return self.body(context + self.state(x) + self.time(time_features(tau, self.config.time_features)))

    def draw(self, context: torch.Tensor, noise: torch.Tensor, steps: int) -> torch.Tensor:
        """Scaled departures (B, L) from ``noise`` (B, L) ~ N(0, I), integrated in ``steps`` Euler
        steps: the same noise gives the same departure."""
        x, dt = noise, 1.0 / steps
        for i in range(steps):
            tau = x.new_full(x.shape[:1], i * dt)
            x = x + dt * self.velocity(x, tau, context)
        return x

    def flow_loss(self, context: torch.Tensor, target: torch.Tensor, noise: torch.Tensor, tau: torch.Tensor):
        """Flow matching's loss: the velocity on the straight path from ``noise`` to the scaled
        departure ``target`` at times ``tau`` against that path's velocity."""
        x = (1 - tau[:, None]) * noise + tau[:, None] * target
        return (self.velocity(x, tau, context) - (target - noise)).square().mean()

    def check_calibration(self) -> None:
        """A ValueError unless the trained scales and the noise's settings are usable: every
        departure scale positive, the pole in [0, 1), the temperature in (0, 4]."""
        if not bool((self.residual_scale > 0).all()):
            raise ValueError("the departures' scales must be positive")
        if not 0.0 <= float(self.noise_decay) < 1.0:
            raise ValueError(f"the noise's pole must be in [0, 1), got {float(self.noise_decay)}")
        if not 0.0 < float(self.temperature) <= 4.0:
            raise ValueError(f"the noise's temperature must be in (0, 4], got {float(self.temperature)}")

    @torch.no_grad()
    def draw_frame(
        self, tracks: list[SampleTrack], features: torch.Tensor, mean: torch.Tensor, *, steps: int
    ) -> torch.Tensor:
        """One frame of each track's character: standardised ``features`` (N, F) and the regression's
        standardised latents ``mean`` (N, L) -> the drawn standardised latents (N, L), the tracks
        moved one frame on. A clip drawn frame by frame and a crowd's characters drawn together get
        the same frames: each track's noise is its own generator's."""
        decay = float(self.noise_decay)
        noise = self.temperature * torch.stack([t.next_noise(decay, self.latent_size) for t in tracks])
        previous = torch.stack([mean[i] if t.previous is None else t.previous for i, t in enumerate(tracks)])
        history = torch.stack([t.history for t in tracks]) if self.config.history else None
        scaled = self.draw(self.context(features, mean, previous, history), noise, steps)
        for i, t in enumerate(tracks):
            t.previous = mean[i].clone()
            if self.config.history:
                t.history = torch.cat([scaled[i : i + 1], t.history[:-1]])
        return mean + scaled * self.residual_scale

    def roll_out(
        self, features: torch.Tensor, mean: torch.Tensor, *, seed: int, steps: int | None = None
    ) -> torch.Tensor:
        """A clip drawn frame after frame from ``seed``: standardised ``features`` (T, F) and the
        regression's standardised latents ``mean`` (T, L) -> the drawn standardised latents (T, L).
        Frame t reads frames <= t only, as a stream does (:meth:`draw_frame`)."""
        steps = self.config.steps if steps is None else steps
        track = [SampleTrack(self, seed)]
        drawn = [
            self.draw_frame(track, features[t : t + 1], mean[t : t + 1], steps=steps)
            for t in range(len(mean))
        ]
        return torch.cat(drawn)


class SampleTrack:
    """One character's draw as it goes on: its seeded generator, its noise (moved on a frame at a
    time), the departures it drew for the last ``history`` frames and the regression's latents of
    the frame before (None before its first frame)."""

    def __init__(self, sampler: ClothSampler, seed: int):
        self.generator = torch.Generator().manual_seed(int(seed))
        self.drive: torch.Tensor | None = None  # the first stage of the noise's filter
        self.noise: torch.Tensor | None = None
        self.history = torch.zeros(sampler.config.history, sampler.latent_size)
        self.previous: torch.Tensor | None = None

    def next_noise(self, decay: float, size: int) -> torch.Tensor:
        """This frame's noise: N(0, I) at every frame, and smooth in time. White noise through two
        first-order filters of pole ``decay`` (an Ornstein-Uhlenbeck process smoothed once more:
        one alone has a rough path, whose second differences showed as jitter), scaled back to unit
        variance, started from the filters' stationary state (two draws at the first frame)."""
        fresh, second = white_noise(self.generator, size, first=self.noise is None)
        if self.noise is None:
            self.drive, self.noise = start_noise(decay, fresh, second)
        else:
            self.drive, self.noise = continue_noise(decay, fresh, (self.drive, self.noise))
        return self.noise


def white_noise(generator: torch.Generator, size: int, *, first: bool) -> torch.Tensor:
    """(2, size): what a character's noise takes from its generator in one frame, N(0, I) values in
    the order drawn: the frame's fresh noise, and at its first frame a second draw that starts the
    filters in their stationary state (zeros after it: nothing drawn). A graph's ``noise`` input
    (:mod:`hrr_garment.export.onnx_model`) takes them so, which makes its draw a Python stream's."""
    fresh = torch.randn(size, generator=generator)
    second = torch.randn(size, generator=generator) if first else torch.zeros(size)
    return torch.stack([fresh, second])


def characters_noise(generators: list[torch.Generator], size: int, first: list[bool]) -> torch.Tensor:
    """(N, 2, size): each character's :func:`white_noise` this frame from its own generator, ``first``
    where the frame is its first: what a graph or a device crowd is fed."""
    return torch.stack([white_noise(g, size, first=bool(f)) for g, f in zip(generators, first)])


def start_noise(decay, fresh: torch.Tensor, second: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The two filters of pole ``decay`` at a character's first frame, stationary: (drive, noise)."""
    return fresh, (fresh + decay * second) / (1 + decay * decay) ** 0.5


def continue_noise(
    decay, fresh: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor]
) -> tuple[torch.Tensor, torch.Tensor]:
    """The two filters' ``state`` (drive, noise) one frame on, ``fresh`` white noise in: each keeps
    unit variance (:meth:`SampleTrack.next_noise`)."""
    drive, noise = state
    drive = decay * drive + (1 - decay * decay) ** 0.5 * fresh
    return drive, decay * noise + (1 - decay * decay) / (1 + decay * decay) ** 0.5 * drive
