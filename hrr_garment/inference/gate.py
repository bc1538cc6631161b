"""The gate of hybrid inference: per motion window, a doubt about retrieving against tau picks
retrieval from the database (doubt below tau) or the code-space decoder's regression; the other
modes force one side (see :class:`.modes.Mode`). The doubt is the motion code's entropy (the
paper's switch, the default) or a judgement of the match itself: one minus its code similarity, or
its motion distance (:data:`~hrr_garment.artifacts.gate_signals.GATE_SIGNALS`). The match signals
search the database for every window, not only for the retrieved ones. The residual mode has no
gate: every window is the regression plus its match's detail (:mod:`hrr_garment.artifacts.residual`);
nor has the detail mode, which returns the regression and the match whose simulated folds it adds
(:mod:`.detail`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..artifacts.bundle import Bundle
from ..artifacts.gate_signals import check_gate_signal, gate_doubt
from ..artifacts.residual import match_regression, residual_latents
from ..models.codes import encode_motion
from .modes import CODE_MODES, Mode


@dataclass
class WindowChoice:
    """What the gate decided for each window (N windows)."""

    latents: np.ndarray  # (N, W, nodes, C) chosen garment latents ((N, 1, nodes, C): last frames only)
    retrieved: np.ndarray  # (N,) bool: the database gave the latents (every window in the residual mode)
    entropy: np.ndarray  # (N,) motion-code entropy
    doubt: np.ndarray  # (N,) the gate signal's value (retrieval where below tau; the entropy by default)
    source: np.ndarray  # (N, 2) int32 (database sequence index, start frame) of retrieved windows, else -1
    detail: bool = False  # the detail mode: ``source`` the matches that lend their folds to ``latents``


def choose_windows(bundle: Bundle, motion_windows: np.ndarray, mode: str, tau: float,
                   exclude: np.ndarray | None = None, last_frame: bool = False,
                   step: torch.nn.Module | None = None, gate: str = "entropy",
                   detail_base: str = "regression") -> WindowChoice:
    """Run the motion encoder on raw feature windows (N, W, F) and pick each window's latents
    (with ``last_frame``, only the last frame's: all that causal inference blends). ``step``:
    see :func:`encode_motion`; ``gate``: the hybrid's signal (see the module docstring);
    ``detail_base``: the latents the detail mode's folds ride on, the regression's or the residual
    mode's."""
    if mode not in CODE_MODES:
        raise ValueError(f"unknown mode {str(mode)!r}; choose one of {', '.join(CODE_MODES)}")
    mode = Mode(mode)
    check_gate_signal(gate)
    db = bundle.database
    enc = encode_motion(bundle.codespace, bundle.motion_stats, bundle.latent_stats, motion_windows,
                        regression=mode.regresses, last_frame=last_frame, step=step)
    n = len(enc.entropy)
    frames = 1 if last_frame else db.latents.shape[1]
    doubt, match = enc.entropy, None
    if mode in (Mode.RESIDUAL, Mode.DETAIL):  # no gate: every window's regression and its best match
        match, similarity = db.search(enc.codes, exclude)
        everywhere = np.ones(n, bool)
        source = np.stack([db.sequence[match], db.start[match]], 1).astype(np.int32)
        latents = enc.regression
        # the detail mode adds the matches' folds (.detail) to the regression's latents or to the
        # residual mode's (the match's own departure from the regression carries the hem's swing,
        # the folds its sharpness)
        if mode is Mode.RESIDUAL or detail_base == "residual":
            matched = db.latents[match, -frames:]
            own = match_regression(bundle.codespace, bundle.motion_stats, bundle.latent_stats, db, match, last_frame, step)
            latents = residual_latents(enc.regression, matched, own, similarity, bundle.residual_weight)
        return WindowChoice(latents, everywhere, enc.entropy, np.asarray(doubt, np.float64), source,
                            detail=mode is Mode.DETAIL)
    if gate != "entropy" and mode is Mode.HYBRID:  # the match decides: search every window first
        match, similarity = db.search(enc.codes, exclude)
        distance = db.motion_distance(enc.standardised, match) if gate == "distance" else None
        doubt = gate_doubt(gate, enc.entropy, similarity, distance)
    retrieved = {Mode.HYBRID: doubt < tau, Mode.REGRESSION: np.zeros(n, bool)}.get(mode, np.ones(n, bool))
    latents = enc.regression.copy() if enc.regression is not None else np.empty((n, frames, *db.latents.shape[2:]), np.float32)
    source = np.full((n, 2), -1, np.int32)
    if retrieved.any():
        rows = np.flatnonzero(retrieved)
        ex = None if exclude is None else np.asarray(exclude)[rows]
        if mode is Mode.NAIVE_NN:
            found = db.nearest_motion(enc.standardised[rows], ex)
        elif match is not None:
            found = match[rows]
        else:
            found, _ = db.search(enc.codes[rows], ex)
        latents[rows] = db.latents[found, -frames:]
        source[rows] = np.stack([db.sequence[found], db.start[found]], 1)
    return WindowChoice(latents, retrieved, enc.entropy, np.asarray(doubt, np.float64), source)
