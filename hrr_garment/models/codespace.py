"""The networks around the shared code space (paper 3.4): motion encoder, garment encoder, decoder.

- :class:`MotionEncoder`: a window of W standardised motion-feature frames (W, 124) -> a GRU over
  the frames -> temporal self-attention over the GRU states (residual, layer norm) -> attention
  pooling with a learned query -> code logits (G x K).
- :class:`GarmentEncoder`: a window of W standardised garment latents, flattened (W x N x 8) -> MLP
  with two hidden layers (1024, ELU) -> code logits of the same shape.
- :class:`LatentDecoder` (the paper's "VQ decoder"): the quantised embedding (G x dim) -> MLP
  mirroring the garment encoder -> the W garment latents (standardised).
- :class:`CodeSpace` holds the three and the shared :class:`~.quantizer.GumbelQuantizer`.

A model trained across bodies (``body_features`` > 0) reads each body's measures
(:mod:`hrr_garment.body.measures`) after every motion frame's features, and a model trained in
several cloths (``material_features`` > 0) the cloth's values (:mod:`hrr_garment.garment.material_range`)
after them: together the last ``condition_features`` columns (with ``clock_conditions`` also the
stillness clock's, the memory's last columns, just before them). The motion encoder sees them with the
motion, and the garment encoder and the decoder take them from the window's last frame
(:meth:`CodeSpace.condition_of`) beside their own inputs, so one code means one movement of the
cloth relative to its body, decoded for the body, the cloth and the time since a stop at hand.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from ..motion.memory import MemorySettings, feature_width
from ..settings import SettingsError, from_settings, require_number
from .quantizer import GumbelQuantizer

REGRESSION_CODES = ("expected", "argmax")


@dataclass(frozen=True)
class CodeSpaceSettings:
    """The code space's sizes: window, groups and classes, embedding and network widths."""

    window: int = 10  # W frames per window
    groups: int = 64  # G
    classes: int = 8  # K
    embedding_dim: int = 8  # values per (group, class) embedding
    hidden: int = 512  # garment encoder / decoder MLP width
    motion_hidden: int = 128  # GRU and attention width (docs/decisions/0033-motion-encoder-128.md)
    attention_heads: int = 4
    dropout: float = 0.0  # after each hidden layer of the garment encoder and the decoder
    memory_seconds: tuple[float, ...] = (
        0.5,
        1.5,
    )  # motion memory's averages' time constants (motion.memory); () for none
    resonator_hz: tuple[float, ...] = (
        0.6,
        1.0,
        1.6,
    )  # the motion memory's resonators' frequencies; () for none
    resonator_damping: float = 0.3  # their damping ratio
    # the motion memory's held averages (motion.memory): averages of the velocities over these
    # seconds of moving time, which keep what the body did before it stopped while it stands; ()
    # for none
    held_seconds: tuple[float, ...] = ()
    # the motion memory's stillness clock (motion.memory): how long the body has stood still, read
    # through exp(-tau / s) for each s; () for none
    still_seconds: tuple[float, ...] = ()
    # whether the garment encoder and the decoder also read the clock's values beside the code, as
    # they read the body's and the cloth's: the creep after a stop is a smooth function of the time
    # since it, which the window's discrete code keeps half of (docs/materials.md, "After a stop")
    clock_conditions: bool = False
    # what the regression decodes: "expected", the embedding averaged over the motion code's
    # distribution (each group's softmax), or "argmax", the most likely class's (the paper's)
    regression_code: str = "expected"
    # body measures appended to every motion frame (hrr_garment.body.measures): set by training
    # when its data holds more than one body; 0, one body (the encoders and decoder read none)
    body_features: int = 0
    # the cloth's values appended after them (hrr_garment.garment.material_range): set by training
    # when its data holds more than one cloth; 0, one cloth
    material_features: int = 0

    def __post_init__(self):
        try:
            spec = MemorySettings(
                seconds=tuple(self.memory_seconds),
                resonator_hz=tuple(self.resonator_hz),
                damping=float(self.resonator_damping),
                still_seconds=tuple(self.still_seconds),
                held_seconds=tuple(self.held_seconds),
            )
        except (TypeError, ValueError) as exc:
            raise SettingsError(f"code space model: {exc}") from None
        object.__setattr__(self, "memory_seconds", spec.seconds)
        object.__setattr__(self, "resonator_hz", spec.resonator_hz)
        object.__setattr__(self, "resonator_damping", spec.damping)
        object.__setattr__(self, "still_seconds", spec.still_seconds)
        object.__setattr__(self, "held_seconds", spec.held_seconds)
        what = "code space model"
        for name, low, high in (
            ("window", 1, 1000),
            ("groups", 1, 4096),
            ("classes", 2, 4096),
            ("embedding_dim", 1, 4096),
            ("hidden", 1, 65536),
            ("motion_hidden", 1, 65536),
            ("attention_heads", 1, 256),
        ):
            require_number(what, name, getattr(self, name), low=low, high=high, whole=True)
        require_number(what, "dropout", self.dropout, low=0, high=1)
        if not isinstance(self.clock_conditions, bool):
            raise SettingsError(
                f"{what}: clock_conditions must be true or false, got {self.clock_conditions!r}"
            )
        if self.clock_conditions and not self.still_seconds:
            raise SettingsError(f"{what}: clock_conditions needs a stillness clock (still_seconds)")
        if self.motion_hidden % self.attention_heads:
            raise SettingsError(
                f"{what}: motion_hidden ({self.motion_hidden}) must divide into attention_heads "
                f"({self.attention_heads})"
            )
        for name in ("body_features", "material_features"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise SettingsError(f"code space model: {name} must be a count >= 0, got {value!r}")
        if self.regression_code not in REGRESSION_CODES:
            raise SettingsError(
                f"code space model: regression_code must be one of {', '.join(REGRESSION_CODES)}, "
                f"got {self.regression_code!r}"
            )

    @property
    def memory(self) -> MemorySettings:
        """The motion memory the features carry (:mod:`hrr_garment.motion.memory`)."""
        return MemorySettings(
            seconds=self.memory_seconds,
            resonator_hz=self.resonator_hz,
            damping=self.resonator_damping,
            still_seconds=self.still_seconds,
            held_seconds=self.held_seconds,
        )

    @property
    def condition_features(self) -> int:
        """The last columns of a motion frame, which condition the garment encoder and the decoder
        beside the code: the stillness clock's with ``clock_conditions`` (the memory's last
        columns), the body's and the cloth's."""
        clock = len(self.still_seconds) if self.clock_conditions else 0
        return clock + self.body_features + self.material_features

    @property
    def features(self) -> int:
        """Motion features per frame: the 124 plain ones, the memory's, the body's and the cloth's."""
        return feature_width(self.memory) + self.body_features + self.material_features

    @classmethod
    def from_dict(cls, values: dict) -> "CodeSpaceSettings":
        return from_settings(cls, values, "code space model")

    def to_dict(self) -> dict:
        """The settings as plain values; no ``material_features`` key for a model of one cloth, no
        ``still_seconds`` for one without a stillness clock, no ``held_seconds`` for one without
        held averages and no ``clock_conditions`` where the clock conditions nothing (its
        bundle.json as before those were read, which older versions also read)."""
        out = asdict(self)
        for key in ("material_features", "still_seconds", "held_seconds", "clock_conditions"):
            if not out[key]:
                del out[key]
        return out


def _mlp(sizes: list[int], dropout: float = 0.0) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2:
            layers.append(nn.ELU())
            if dropout > 0:
                layers.append(nn.Dropout(dropout))
    return nn.Sequential(*layers)


class MotionEncoder(nn.Module):
    """Motion windows (B, W, F) -> code logits (B, G x K): GRU, self-attention, attention pooling."""

    def __init__(self, features: int, logits: int, hidden: int = 256, heads: int = 4):
        super().__init__()
        self.inp = nn.Linear(features, hidden)
        self.gru = nn.GRU(hidden, hidden, batch_first=True)
        self.attention = nn.MultiheadAttention(hidden, heads, batch_first=True)
        self.norm = nn.LayerNorm(hidden)
        self.query = nn.Parameter(torch.randn(1, 1, hidden) / math.sqrt(hidden))
        self.pool = nn.MultiheadAttention(hidden, heads, batch_first=True)
        self.out = nn.Sequential(nn.LayerNorm(hidden), nn.Linear(hidden, logits))

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        """(B, W, F) -> (B, G * K) logits."""
        h, _ = self.gru(torch.nn.functional.elu(self.inp(windows)))
        h = self.norm(h + self.attention(h, h, h, need_weights=False)[0])
        pooled = self.pool(self.query.expand(h.shape[0], -1, -1), h, h, need_weights=False)[0][:, 0]
        return self.out(pooled)


class GarmentEncoder(nn.Module):
    """Garment latent windows -> code logits (B, G x K): an MLP."""

    def __init__(self, size: int, logits: int, hidden: int = 1024, dropout: float = 0.0):
        super().__init__()
        self.net = _mlp([size, hidden, hidden, logits], dropout)

    def forward(self, latents: torch.Tensor, condition: torch.Tensor | None = None) -> torch.Tensor:
        """(B, W, N, C) or (B, W * N * C), and the standardised body measures and cloth values (B, c)
        of a model trained across bodies or cloths -> (B, G * K) logits."""
        flat = latents.reshape(len(latents), -1)
        return self.net(flat if condition is None else torch.cat([flat, condition], 1))


class LatentDecoder(nn.Module):
    """A code's embedding -> the window's garment latents: an MLP."""

    def __init__(self, embedding: int, size: int, hidden: int = 1024, dropout: float = 0.0):
        super().__init__()
        self.net = _mlp([embedding, hidden, hidden, size], dropout)

    def forward(self, embedding: torch.Tensor) -> torch.Tensor:
        """(B, G * dim) -> (B, W * N * C) standardised latents."""
        return self.net(embedding)


class CodeSpace(nn.Module):
    """Motion encoder, garment encoder, quantiser and decoder for windows of ``latent_shape``
    (N nodes x C values) garment latents and ``features``-wide motion frames."""

    def __init__(self, config: CodeSpaceSettings, features: int, latent_shape: tuple[int, int]):
        super().__init__()
        self.config, self.features, self.latent_shape = config, features, tuple(latent_shape)
        size = config.window * latent_shape[0] * latent_shape[1]
        self.quantizer = GumbelQuantizer(config.groups, config.classes, config.embedding_dim)
        self.motion_encoder = MotionEncoder(
            features, self.quantizer.logits_size, config.motion_hidden, config.attention_heads
        )
        condition = config.condition_features
        self.garment_encoder = GarmentEncoder(
            size + condition, self.quantizer.logits_size, config.hidden, config.dropout
        )
        self.decoder = LatentDecoder(
            self.quantizer.embedding_size + condition, size, config.hidden, config.dropout
        )

    def condition_of(self, motion: torch.Tensor) -> torch.Tensor | None:
        """The standardised conditions (B, c) of motion windows (B, W, F), the clock's, body measures
        and cloth values as the model reads them: their last frame's last ``condition_features``
        columns; None for a model that reads none."""
        c = self.config.condition_features
        return motion[:, -1, motion.shape[-1] - c :] if c else None

    def decode(
        self, embedding: torch.Tensor, last_frame: bool = False, condition: torch.Tensor | None = None
    ) -> torch.Tensor:
        """(B, G * dim) and, for a model trained across bodies or cloths, their values
        (:meth:`condition_of`) ->
        (B, W, N, C) standardised latents; with ``last_frame`` only the window's last frame,
        (B, 1, N, C), which is all causal inference uses: the output layer's other rows (nine
        tenths of the decoder's weights) are skipped."""
        if (condition is None) != (self.config.condition_features == 0):
            raise ValueError(
                f"the decoder reads {self.config.condition_features} clock, body and cloth values; "
                f"{'none' if condition is None else condition.shape[-1]} given"
            )
        if condition is not None:
            embedding = torch.cat([embedding, condition], 1)
        if not last_frame:
            return self.decoder(embedding).reshape(embedding.shape[0], self.config.window, *self.latent_shape)
        *hidden, out = self.decoder.net
        h = embedding
        for layer in hidden:
            h = layer(h)
        n = self.latent_shape[0] * self.latent_shape[1]
        return torch.nn.functional.linear(h, out.weight[-n:], out.bias[-n:]).reshape(
            embedding.shape[0], 1, *self.latent_shape
        )
