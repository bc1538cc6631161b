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
from ..artifacts.gate_signals import gate_doubt
from ..artifacts.residual import match_regression, residual_latents, residual_scale
from ..models.codes import encode_motion, window_conditions
from .modes import CODE_MODES, Mode
from .run_settings import ResolvedRun


@dataclass
class WindowChoice:
    """What the gate decided for each window (N windows)."""

    latents: np.ndarray  # (N, W, nodes, C) chosen garment latents ((N, 1, nodes, C): last frames only)
    retrieved: np.ndarray  # (N,) bool: the latents are the database window's, as simulated
    entropy: np.ndarray  # (N,) motion-code entropy
    doubt: np.ndarray  # (N,) the gate signal's value (retrieval where below tau; the entropy by default)
    match: (
        np.ndarray
    )  # (N, 2) int32 (database sequence index, start frame) of the window that gave or lent, else -1
    lends_folds: bool = False  # the detail mode: ``match`` lends its simulated folds to ``latents``
    # (N,) bool: the latents change with the match (retrieved windows, and every residual window's),
    # so a change of match is a change of source for causal inertialization (None: ``retrieved``)
    follows_match: np.ndarray | None = None
    # (N, W or 1, nodes, C) the part of ``latents`` that is one source whatever the match (the
    # regression under a residual): causal paths inertialize only the rest (None: all of it)
    continuous: np.ndarray | None = None
    # (N, W or 1, nodes, C) the share of ``latents`` that swings as the regression does: the
    # regression less the share of it the residual's match replaced (inference/swing.py scales its
    # departure). None: all of ``latents``, or a run without the swing's gain
    regression_part: np.ndarray | None = None
    # (N, W or 1, nodes, C) the regression the residual and detail modes add to (a match's
    # departure, its folds, and the swing and settling on them): the push-out takes the additions
    # back where they carry the cloth into the body (.take_back). None: the other modes (a retrieved
    # window is a simulation of its own, not an addition; the regression and the sample mode run as
    # the torch step runs them)
    regression: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.follows_match is None:
            self.follows_match = self.retrieved


def choose_windows(
    bundle: Bundle,
    motion_windows: np.ndarray,
    run: ResolvedRun,
    *,
    exclude: np.ndarray | None = None,
    last_frame: bool = False,
    step: torch.nn.Module | None = None,
    gates: np.ndarray | None = None,
) -> WindowChoice:
    """Run the motion encoder on raw feature windows (N, W, F) and pick each window's latents as
    ``run`` asks (its mode, gate and tau, the detail mode's base; with ``last_frame``, only the
    last frame's latents: all that causal inference blends). ``exclude``: (N,) a database sequence
    each window may not retrieve from; ``step`` and ``gates``: see :func:`encode_motion`."""
    mode = run.mode
    if mode not in CODE_MODES:
        raise ValueError(f"unknown mode {str(mode)!r}; choose one of {', '.join(CODE_MODES)}")
    db = bundle.database
    enc = encode_motion(
        bundle.codespace,
        bundle.motion_stats,
        bundle.latent_stats,
        motion_windows=motion_windows,
        regression=mode.regresses,
        last_frame=last_frame,
        step=step,
        gates=gates,
    )
    n = len(enc.entropy)
    frames = 1 if last_frame else db.latents.shape[1]
    conditions = window_conditions(bundle.codespace, enc)
    doubt, match = enc.entropy, None
    if mode in (Mode.RESIDUAL, Mode.DETAIL):  # no gate: every window's regression and its best match
        match, similarity = db.search(enc.codes, exclude, conditions)
        matched = np.stack([db.sequence[match], db.start[match]], 1).astype(np.int32)
        latents = enc.regression
        # the detail mode adds the matches' folds (.detail) to the regression's latents or to the
        # residual mode's (the match's own departure from the regression carries the hem's swing,
        # the folds its sharpness)
        residual = mode is Mode.RESIDUAL or run.fold_base == "residual"
        part = None
        if residual:
            own = match_regression(
                bundle.codespace,
                bundle.motion_stats,
                bundle.latent_stats,
                database=db,
                rows=match,
                last_frame=last_frame,
                step=step,
            )
            latents = residual_latents(
                enc.regression,
                db.latents[match, -frames:],
                own,
                similarity=similarity,
                weight=bundle.residual_weight,
                nodes=bundle.residual_nodes,
            )
            if run.swing != 1.0:  # only the swing's gain reads it (inference/swing.py)
                # where the match's motion is the query's (the game's own clips) the residual replaces
                # that share of the regression, damped swing included, by the match's simulation
                part = (
                    1.0 - residual_scale(similarity, bundle.residual_weight, bundle.residual_nodes)
                ) * enc.regression
        # on the regression, a detail window's latents are one continuous source whatever lends the
        # folds; on the residual they change with the match, which causal inference inertializes
        # (without it a stream of the default look jumped at every change of match: 2 x the jitter),
        # the match's departure only: the regression under it is continuous, and extrapolated at
        # every change it lagged (causal PVE 33.8 against the regression's 31.7 mm at weight 0)
        return WindowChoice(
            latents,
            np.zeros(n, bool),
            enc.entropy,
            np.asarray(doubt, np.float64),
            matched,
            lends_folds=mode is Mode.DETAIL,
            follows_match=np.full(n, residual),
            continuous=enc.regression if residual else None,
            regression_part=part,
            regression=enc.regression,
        )
    if run.gate != "entropy" and mode is Mode.HYBRID:  # the match decides: search every window first
        match, similarity = db.search(enc.codes, exclude, conditions)
        distance = db.motion_distance(enc.standardised, match) if run.gate == "distance" else None
        doubt = gate_doubt(run.gate, enc.entropy, similarity, distance=distance)
    retrieved = {
        Mode.HYBRID: doubt < run.tau,
        Mode.REGRESSION: np.zeros(n, bool),
        Mode.SAMPLE: np.zeros(n, bool),  # the regression, which the sampler then departs from
    }.get(mode, np.ones(n, bool))
    latents = (
        enc.regression.copy()
        if enc.regression is not None
        else np.empty((n, frames, *db.latents.shape[2:]), np.float32)
    )
    source = np.full((n, 2), -1, np.int32)
    if retrieved.any():
        rows = np.flatnonzero(retrieved)
        ex = None if exclude is None else np.asarray(exclude)[rows]
        if mode is Mode.NAIVE_NN:
            found = db.nearest_motion(enc.standardised[rows], ex)
        elif match is not None:
            found = match[rows]
        else:
            found, _ = db.search(enc.codes[rows], ex, None if conditions is None else conditions[rows])
        latents[rows] = db.latents[found, -frames:]
        source[rows] = np.stack([db.sequence[found], db.start[found]], 1)
    return WindowChoice(latents, retrieved, enc.entropy, np.asarray(doubt, np.float64), source)


def frame_gates(bundle: Bundle, step, frames: np.ndarray) -> np.ndarray | None:
    """Raw per-frame features (n, F) -> their GRU input gates (n, 3H) for a native causal ``step``
    (:meth:`~hrr_garment.models.native_codes.NativeWindowCodes.frame_gates`), or None where the step
    is PyTorch's. Causal windows slide by one frame, so the frames' gates are computed once and
    each window's passed to :func:`choose_windows` (``gates``)."""
    if not hasattr(step, "frame_gates"):
        return None
    return step.frame_gates(bundle.motion_stats.normalize(frames))
