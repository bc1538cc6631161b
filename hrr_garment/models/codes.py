"""The code space's window step, shared by calibration (``train``) and inference: standardised
motion windows -> motion encoder -> per-group entropy and argmax code -> the regression's
embedding (the code distribution's mean, or the argmax classes') -> the code-space decoder's
regressed garment latents.

:class:`WindowCodes` is the PyTorch form; :mod:`.native_codes` computes the same in C for causal
inference; :func:`traced_window_codes` is the TorchScript form a stream uses without a compiler.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import torch

from .quantizer import group_entropy


@dataclass
class MotionCodes:
    """The motion encoder's output for N windows."""

    entropy: np.ndarray  # (N,) mean per-group entropy of the code distribution (nats)
    codes: np.ndarray  # (N, G) uint8 argmax classes
    regression: np.ndarray | None  # (N, W, nodes, C) decoder latents (not standardised), when asked
    windows: np.ndarray  # (N, W, F) the raw motion windows
    motion_stats: object  # their standardisation (FeatureStats)

    @cached_property
    def standardised(self) -> np.ndarray:
        """(N, W, F) the standardised motion windows, made when first read: a crowd's step with its
        frames' gates reads none of them (half a millisecond of 64 characters' step)."""
        return self.motion_stats.normalize(self.windows)


def regression_embedding(codespace, logits: torch.Tensor) -> torch.Tensor:
    """What the regression decodes from grouped motion logits (B, G, K): the embedding averaged
    over each group's softmax (``regression_code`` "expected": the code distribution's mean, which
    the decoder maps closer to the conditional mean than any one code; -0.8 mm on real-quick
    validation windows, docs/codespace.md) or the argmax class's (the paper's)."""
    q = codespace.quantizer
    if codespace.config.regression_code == "expected":
        return q.embed(torch.softmax(logits, -1))
    return q.embed(torch.nn.functional.one_hot(logits.argmax(-1), q.classes).to(logits.dtype))


def window_conditions(codespace, codes: MotionCodes) -> np.ndarray | None:
    """The standardised body measures and cloth values (N, c) of the windows ``codes`` were made
    of, for a model trained across bodies or cloths (retrieval prefers matches from near bodies in
    near cloths: :meth:`~hrr_garment.artifacts.database.CodeDatabase.search`); None for a model of
    one body in one cloth."""
    c = codespace.config.condition_features
    if not c:
        return None
    return codes.motion_stats.normalize(codes.windows[:, -1])[:, -c:]  # the last frame's: not every window's


class WindowCodes(torch.nn.Module):
    """Standardised motion windows (B, W, F) -> (entropy (B,), argmax classes (B, G), regressed
    standardised latents (B, W or 1, nodes, C), or an empty tensor without ``regression``)."""

    def __init__(self, codespace, regression: bool = True, last_frame: bool = False):
        super().__init__()
        self.codespace, self.regression, self.last_frame = codespace, regression, last_frame

    def forward(self, windows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        q = self.codespace.quantizer
        logits = q.split(self.codespace.motion_encoder(windows))
        idx = logits.argmax(-1)
        if not self.regression:
            return group_entropy(logits), idx, torch.empty(0)
        embedding = regression_embedding(self.codespace, logits)
        return (
            group_entropy(logits),
            idx,
            self.codespace.decode(embedding, self.last_frame, self.codespace.condition_of(windows)),
        )


def traced_window_codes(codespace, window: int, features: int, regression: bool = True) -> torch.nn.Module:
    """:class:`WindowCodes` for one causal window at a time (streaming without a C compiler; the
    native window step of :mod:`.native_codes` is used where compiled), traced
    and frozen by TorchScript: the same operations without Python's per-module overhead (about 1
    ms of a push).
    Falls back to the eager module where tracing fails."""
    step = WindowCodes(codespace.eval(), regression, last_frame=True).eval()
    try:
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore")  # batch size 1 is fixed on purpose
            return torch.jit.freeze(torch.jit.trace(step, torch.zeros(1, window, features)))
    except RuntimeError:
        return step


ENCODE_BATCH = 512  # windows per call of the step: bounds the memory of a long clip


@torch.no_grad()
def encode_motion(
    codespace,
    motion_stats,
    latent_stats,
    motion_windows: np.ndarray,
    regression: bool = True,
    last_frame: bool = False,
    step: torch.nn.Module | None = None,
    gates: np.ndarray | None = None,
) -> MotionCodes:
    """Raw feature windows (N, W, F) -> codes, entropies and (optionally) regressed latents, of
    every frame of each window or, with ``last_frame``, of its last frame only (N, 1, nodes, C).
    ``step``: a prepared :class:`WindowCodes` with the same settings (streaming); ``gates``: (N, W,
    3H) the windows' frames' GRU input gates, kept by the caller as the frames came (a view is
    fine), for a native ``step`` (:meth:`~.native_codes.NativeWindowCodes.frame_gates`)."""
    if codespace.training:
        codespace.eval()
    step = WindowCodes(codespace, regression, last_frame) if step is None else step
    codes_of = MotionCodes(None, None, None, motion_windows, motion_stats)
    # with the frames' gates the step reads only each window's last frame (its body measures)
    std = codes_of.standardised if gates is None else motion_stats.normalize(motion_windows[:, -1:])
    entropy, codes, reg = [], [], []
    for i in range(0, len(std), ENCODE_BATCH):
        x = torch.from_numpy(std[i : i + ENCODE_BATCH])
        h, idx, r = step(x) if gates is None else step(x, gates[i : i + ENCODE_BATCH])
        entropy.append(h.numpy())
        codes.append(idx.numpy().astype(np.uint8))
        reg.append(r.numpy())
    latents = None
    if regression:
        r = np.concatenate(reg)
        latents = latent_stats.denormalize(r.reshape(*r.shape[:2], -1)).reshape(r.shape)
    codes_of.entropy, codes_of.codes, codes_of.regression = (
        np.concatenate(entropy),
        np.concatenate(codes),
        latents,
    )
    return codes_of
