"""Gate calibration (its signal and threshold tau) and per-mode validation errors of a trained code
space (at training time, and again from a saved bundle: :func:`evaluate_bundle`).

For every validation window the gate has a doubt about retrieving: the motion code's entropy H
(mean per group, nats, 0 .. log K; the paper's), one minus the match's code similarity, or the
match's motion distance (:data:`~hrr_garment.artifacts.gate_signals.GATE_SIGNALS`); retrieval where the
doubt is below tau, regression otherwise. Both candidates are decoded to vertices with the mesh
autoencoder and compared with the simulated frames (:mod:`.calibration_windows`), so the sweep over
tau is a cheap selection between two precomputed errors per window (:mod:`.tau_sweep`). Each
signal's tau is its sweep's best, and the gate is the signal whose optimum is lowest (ties: the
first of GATE_SIGNALS, the paper's entropy). The residual mode's weight is calibrated on the same
windows (:mod:`.residual_calibration`).

These are window-level errors; blending overlapping windows at inference (issue "hybrid
inference") averages them per frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from ..artifacts.bundle import Bundle
from ..artifacts.bundle_writer import BundleParts
from ..artifacts.gate_signals import GATE_SIGNALS
from ..data.dataset import DatasetError, GarmentDataset
from ..data.windows import dataset_features
from .autoencoder_settings import refine_settings
from .calibration_windows import MAX_WINDOWS, calibration_windows, predict_windows, window_errors_mm
from .residual_calibration import choose_residual_weight, residual_errors
from .tau_sweep import TauSweep, sweep_tau
from .training_frames import body_frames


@dataclass
class ModeErrors:
    """Per-window validation errors (mm) of both candidates, the autoencoder's own reconstruction
    (the floor), each gate signal's doubts, and the tau sweep over each."""

    regression: np.ndarray
    retrieval: np.ndarray
    autoencoder: np.ndarray
    doubts: dict[str, np.ndarray]  # gate signal -> (N,) doubt per window
    sweeps: dict[str, TauSweep]  # gate signal -> its sweep
    residual: dict[float, np.ndarray] | None = None  # residual weight -> (N,) errors (None: not calibrated)

    @property
    def entropy(self) -> np.ndarray:
        return self.doubts["entropy"]

    @property
    def gate(self) -> str:
        """The calibrated gate: the signal whose sweep reaches the lowest error (ties: the paper's
        entropy, then the order of GATE_SIGNALS)."""
        return min(self.sweeps, key=lambda g: (min(self.sweeps[g].errors_mm), GATE_SIGNALS.index(g)))

    @property
    def sweep(self) -> TauSweep:
        """The calibrated gate's sweep."""
        return self.sweeps[self.gate]

    def summary(self, tau: float, gate: str = "entropy") -> dict:
        retrieve = self.doubts[gate] < tau
        return {
            "hybrid": float(np.where(retrieve, self.retrieval, self.regression).mean()),
            "regression": float(self.regression.mean()),
            "retrieval": float(self.retrieval.mean()),
            "autoencoder": float(self.autoencoder.mean()),
            "retrieval_usage": float(retrieve.mean()),
            "tau": tau,
            "gate": gate,
        }

    def residual_calibration(self) -> dict | None:
        """The residual mode's weight (:func:`choose_residual_weight`), its error and every
        weight's, or None where it was not evaluated."""
        return None if self.residual is None else choose_residual_weight(self.regression, self.residual)

    def gates(self) -> dict[str, dict]:
        """Each signal's calibration: its best tau, the hybrid's error there and its retrieval usage."""
        return {
            g: {
                "tau": s.best_tau,
                "validation_mm": min(s.errors_mm),
                "retrieval_usage": s.retrieval_usage[s.taus.index(s.best_tau)],
            }
            for g, s in self.sweeps.items()
        }


def window_mode_errors(
    model: BundleParts | Bundle,
    motion: dict[str, np.ndarray],
    frames: dict[str, np.ndarray],
    *,
    encoding: dict,
    max_windows: int | None = MAX_WINDOWS,
    windows: list[tuple[str, int]] | None = None,
    progress: bool = False,
) -> ModeErrors:
    """Both modes' window-level errors of ``model`` (a bundle, or the parts of one being trained:
    its code space, statistics, database and mesh autoencoder) on windows of the sequences ``motion``
    (features (T, F)) / ``frames`` (heading-frame vertices (T, V, 3)), decoded with the autoencoder's fast
    decoder: ``windows`` ((sequence, first frame) pairs; default every window of every sequence), or
    ``max_windows`` of them evenly spaced. ``encoding``: the autoencoder stage's ``refine_steps``
    and ``refine_lr``, which the floor's latents repeat. ``progress``: bars over the floor's
    encoding and the residual weights, the slow parts at full resolution on a CPU."""
    codespace, autoencoder = model.codespace, model.autoencoder
    motion_stats, latent_stats, database = model.motion_stats, model.latent_stats, model.database
    refine_steps, refine_lr = encoding["refine_steps"], encoding["refine_lr"]
    w = codespace.config.window
    windows, m, truth = calibration_windows(motion, frames, w, windows=windows, max_windows=max_windows)
    # the floor: each frame's own latent, encoded as the training targets were (each frame fitted
    # once, on its own: fit_latents gives a frame the same latent whatever batch it is in)
    needed: dict[str, set[int]] = {}
    for n, s in windows:
        needed.setdefault(n, set()).update(range(s, s + w))
    own_frames = {}
    for n, rows in tqdm(needed.items(), desc="calibration floor", unit="sequence", disable=not progress):
        rows_sorted = np.array(sorted(rows))
        fitted = autoencoder.fit_latents(
            torch.from_numpy(frames[n][rows_sorted]), refine_steps, refine_lr
        ).numpy()
        own_frames[n] = np.zeros((len(frames[n]), *fitted.shape[1:]), fitted.dtype)
        own_frames[n][rows_sorted] = fitted
    own = np.stack([own_frames[n][s : s + w] for n, s in windows])
    pred = predict_windows(codespace, m, motion_stats, latent_stats=latent_stats, database=database)
    decode = autoencoder.inference_decoder()
    err_reg = window_errors_mm(decode, pred.regression, truth)
    err_ret = window_errors_mm(decode, pred.retrieval, truth)
    err_ae = window_errors_mm(decode, own, truth)
    doubts = pred.doubts()
    return ModeErrors(
        err_reg,
        err_ret,
        err_ae,
        doubts,
        {g: sweep_tau(d, err_reg, err_ret) for g, d in doubts.items()},
        residual_errors(pred, decode, truth, progress=progress),
    )


def evaluate_bundle(bundle, dataset: str | Path, split: str = "val") -> dict:
    """Recompute a bundle's per-mode window errors on a dataset split (the numbers ``hrr-train``
    reports for ``val``); the dataset must be of the bundle's garment and template."""
    ds = GarmentDataset(dataset)
    if (
        ds.garment != bundle.garment
        or ds.template.num_vertices != bundle.template.num_vertices
        or not np.array_equal(ds.template.faces, bundle.template.faces)
    ):
        raise DatasetError(
            dataset,
            f"is a {ds.garment} dataset with {ds.template.num_vertices} vertices; the model in "
            f"{bundle.folder} is for {bundle.garment} with {bundle.template.num_vertices}",
        )
    names = ds.splits.get(split, [])
    if not names:
        raise DatasetError(dataset, f"has no {split!r} sequences")
    encoding = refine_settings(bundle.manifest.encoding or {})
    modes = window_mode_errors(
        bundle,
        dataset_features(ds, names, bundle.codespace.config),
        {n: body_frames(ds, [n]) for n in names},
        encoding=encoding,
    )
    return modes.summary(bundle.tau, bundle.gate)
