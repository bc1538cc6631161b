"""The validation windows calibration decodes, and both candidates on them: each window's
regression and best database match (with what the gate signals and the residual mode need), and
their per-window errors against the simulated frames (per-vertex error in the heading frame, mean
over the window's W frames and vertices, in mm)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..artifacts.database import CodeDatabase
from ..artifacts.gate_signals import GATE_SIGNALS, gate_doubt
from ..artifacts.residual import match_regression, residual_latents
from ..models.codes import encode_motion, window_conditions
from ..models.codespace import CodeSpace
from ..motion.features import FeatureStats

# Windows the tau sweep decodes at most (evenly spaced; stride-1 windows overlap in W - 1 frames, so
# a sample loses little): all 11,600 of the real-motion library's validation windows, three modes of
# W frames each, took 10 minutes to decode on the Xeon and 40 on a 2-core AVX2 machine.
MAX_WINDOWS = 2000


@dataclass
class WindowPredictions:
    """Both candidates (regression and retrieval) for every validation window, and what residual
    retrieval needs."""

    entropy: np.ndarray  # (N,) motion-code entropy
    regression: np.ndarray  # (N, W, nodes, C) latents from the decoder
    retrieval: np.ndarray  # (N, W, nodes, C) latents of the best database match
    similarity: np.ndarray  # (N,) cosine similarity of that match's code to the motion code
    distance: np.ndarray | None  # (N,) that match's motion distance (None: the database has no motion)
    match_regression: np.ndarray | None  # (N, W, nodes, C) the regression of the match's own motion (idem)

    def residual(self, weight: float) -> np.ndarray:
        """The residual mode's latents at ``weight``."""
        return residual_latents(
            self.regression, self.retrieval, self.match_regression, similarity=self.similarity, weight=weight
        )

    def doubts(self) -> dict[str, np.ndarray]:
        """Each gate signal's doubt per window (the signals this database supports)."""
        return {
            g: gate_doubt(g, self.entropy, self.similarity, distance=self.distance)
            for g in GATE_SIGNALS
            if g != "distance" or self.distance is not None
        }


def predict_windows(
    model: CodeSpace,
    motion: np.ndarray,
    motion_stats: FeatureStats,
    latent_stats: FeatureStats,
    database: CodeDatabase,
    exclude: np.ndarray | None = None,
) -> WindowPredictions:
    """Both candidates for every motion window (N, W, F) (raw features)."""
    enc = encode_motion(model, motion_stats, latent_stats, motion_windows=motion)
    match, similarity = database.search(enc.codes, exclude, window_conditions(model, enc))
    distance = own = None
    if database.motion is not None:
        distance = database.motion_distance(enc.standardised, match)
        own = match_regression(model, motion_stats, latent_stats, database=database, rows=match)
    return WindowPredictions(enc.entropy, enc.regression, database.latents[match], similarity, distance, own)


def window_errors_mm(decode, latents: np.ndarray, truth: np.ndarray, batch: int = 64) -> np.ndarray:
    """Per-window per-vertex error (mm): latents (N, W, nodes, C), truth (N, W, V, 3) heading frame;
    ``decode`` maps (B, nodes, C) tensors to (B, V, 3)."""
    n, w = latents.shape[:2]
    flat = torch.from_numpy(np.ascontiguousarray(latents.reshape(n * w, *latents.shape[2:])))
    out = np.empty(n * w, np.float64)
    for i in range(0, n * w, batch):
        pred = decode(flat[i : i + batch]).numpy()
        out[i : i + batch] = np.linalg.norm(
            pred - truth.reshape(n * w, *truth.shape[2:])[i : i + batch], axis=-1
        ).mean(-1)
    return 1000.0 * out.reshape(n, w).mean(1)


def calibration_windows(
    motion: dict[str, np.ndarray],
    frames: dict[str, np.ndarray],
    window: int,
    windows: list[tuple[str, int]] | None = None,
    max_windows: int | None = MAX_WINDOWS,
) -> tuple[list[tuple[str, int]], np.ndarray, np.ndarray]:
    """The (sequence, first frame) pairs calibration decodes (``windows``, default every window of
    every sequence; at most ``max_windows`` of them, evenly spaced) and their motion (N, W, F) and
    true frames (N, W, V, 3)."""
    if windows is None:
        windows = [(n, s) for n in motion for s in range(len(motion[n]) - window + 1)]
    if max_windows is not None and len(windows) > max_windows:
        windows = [windows[i] for i in np.linspace(0, len(windows) - 1, max_windows).round().astype(int)]
    if not windows:
        raise ValueError(f"no validation sequence has {window} frames or more")
    m = np.stack([motion[n][s : s + window] for n, s in windows])
    truth = np.stack([frames[n][s : s + window] for n, s in windows])
    return windows, np.ascontiguousarray(m), truth
