"""The gate of hybrid inference: per motion window, the motion code's entropy against tau picks
retrieval from the database (low entropy: a confident code) or the code-space decoder's
regression; the other modes force one side (see :class:`.modes.Mode`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..artifacts.bundle import Bundle
from ..models.codes import encode_motion
from .modes import CODE_MODES, Mode


@dataclass
class WindowChoice:
    """What the gate decided for each window (N windows)."""

    latents: np.ndarray  # (N, W, nodes, C) chosen garment latents ((N, 1, nodes, C): last frames only)
    retrieved: np.ndarray  # (N,) bool
    entropy: np.ndarray  # (N,) motion-code entropy
    source: np.ndarray  # (N, 2) int32 (database sequence index, start frame) of retrieved windows, else -1


def choose_windows(bundle: Bundle, motion_windows: np.ndarray, mode: str, tau: float,
                   exclude: np.ndarray | None = None, last_frame: bool = False,
                   step: torch.nn.Module | None = None) -> WindowChoice:
    """Run the motion encoder on raw feature windows (N, W, F) and pick each window's latents
    (with ``last_frame``, only the last frame's: all that causal inference blends). ``step``:
    see :func:`encode_motion`."""
    if mode not in CODE_MODES:
        raise ValueError(f"unknown mode {str(mode)!r}; choose one of {', '.join(CODE_MODES)}")
    mode = Mode(mode)
    db = bundle.database
    enc = encode_motion(bundle.codespace, bundle.motion_stats, bundle.latent_stats, motion_windows,
                        regression=mode.regresses, last_frame=last_frame, step=step)
    n = len(enc.entropy)
    retrieved = {Mode.HYBRID: enc.entropy < tau, Mode.REGRESSION: np.zeros(n, bool)}.get(mode, np.ones(n, bool))
    frames = 1 if last_frame else db.latents.shape[1]
    latents = enc.regression.copy() if enc.regression is not None else np.empty((n, frames, *db.latents.shape[2:]), np.float32)
    source = np.full((n, 2), -1, np.int32)
    if retrieved.any():
        rows = np.flatnonzero(retrieved)
        ex = None if exclude is None else np.asarray(exclude)[rows]
        if mode is Mode.NAIVE_NN:
            match = db.nearest_motion(enc.standardised[rows], ex)
        else:
            match, _ = db.search(enc.codes[rows], ex)
        latents[rows] = db.latents[match, -frames:]
        source[rows] = np.stack([db.sequence[match], db.start[match]], 1)
    return WindowChoice(latents, retrieved, enc.entropy, source)
