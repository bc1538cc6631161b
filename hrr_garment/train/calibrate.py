"""Gate calibration (its signal and threshold tau) and per-mode validation errors of a trained code
space (at training time, and again from a saved bundle: :func:`evaluate_bundle`).

For every validation window the gate has a doubt about retrieving: the motion code's entropy H
(mean per group, nats, 0 .. log K; the paper's), one minus the match's code similarity, or the
match's motion distance (:data:`~hrr_garment.artifacts.gate_signals.GATE_SIGNALS`); retrieval where the
doubt is below tau, regression otherwise. Both candidates are decoded to vertices with the mesh
autoencoder and compared with the simulated frames (per-vertex error in the heading frame, mean
over the window's W frames and vertices), so the sweep over tau is a cheap selection between two
precomputed errors per window. tau = 0 is regression only, tau = inf retrieval only; each signal's
tau is its sweep's lowest mean error (ties: the smallest tau, i.e. the least retrieval), and the
gate is the signal whose optimum is lowest (ties: the first of GATE_SIGNALS, the paper's entropy).

The residual mode (:mod:`hrr_garment.artifacts.residual`) is calibrated on the same windows: its
weight is the largest of 0 (plain regression) and :data:`RESIDUAL_WEIGHTS` whose mean error stays
within :data:`ACCURACY_ALLOWANCE` of the regression's.

These are window-level errors; blending overlapping windows at inference (issue "hybrid
inference") averages them per frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from ..artifacts.bundle import Bundle
from ..artifacts.bundle_writer import BundleParts
from ..artifacts.database import CodeDatabase
from ..artifacts.gate_signals import GATE_SIGNALS, gate_doubt
from ..artifacts.residual import ACCURACY_ALLOWANCE, RESIDUAL_WEIGHTS, match_regression, residual_latents
from ..data.dataset import DatasetError, GarmentDataset
from ..data.windows import dataset_features
from ..models.codes import encode_motion, window_bodies
from ..models.codespace import CodeSpace
from ..motion.features import FeatureStats
from .autoencoder_settings import refine_settings
from .training_frames import body_frames

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
    match, similarity = database.search(enc.codes, exclude, window_bodies(model, enc))
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


@dataclass
class ModeErrors:
    """Per-window validation errors (mm) of both candidates, the autoencoder's own reconstruction
    (the floor), each gate signal's doubts, and the tau sweep over each."""

    regression: np.ndarray
    retrieval: np.ndarray
    autoencoder: np.ndarray
    doubts: dict[str, np.ndarray]  # gate signal -> (N,) doubt per window
    sweeps: dict[str, "TauSweep"]  # gate signal -> its sweep
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
    def sweep(self) -> "TauSweep":
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
    its code space, statistics, database and mesh autoencoder) on windows of the sequences ``motion`` (features (T, F)) /
    ``frames`` (heading-frame vertices (T, V, 3)), decoded with the autoencoder's fast decoder:
    ``windows`` ((sequence, first frame) pairs; default every window of every sequence), or
    ``max_windows`` of them evenly spaced. ``encoding``: the autoencoder stage's ``refine_steps``
    and ``refine_lr``, which the floor's latents repeat. ``progress``: bars over the floor's
    encoding and the residual weights, the slow parts at full resolution on a CPU."""
    codespace, autoencoder = model.codespace, model.autoencoder
    motion_stats, latent_stats, database = model.motion_stats, model.latent_stats, model.database
    refine_steps, refine_lr = encoding["refine_steps"], encoding["refine_lr"]
    w = codespace.config.window
    windows, m, truth = calibration_windows(motion, frames, w, windows, max_windows)
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
    pred = predict_windows(codespace, m, motion_stats, latent_stats, database)
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
        residual_errors(pred, decode, truth, progress),
    )


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


def residual_errors(
    pred: WindowPredictions, decode, truth: np.ndarray, progress: bool = False
) -> dict[float, np.ndarray] | None:
    """Per-window errors (mm) of the residual mode at each of :data:`RESIDUAL_WEIGHTS` (None where
    the database has no motion windows to regress the matches from)."""
    if pred.match_regression is None:
        return None
    return {
        w: window_errors_mm(decode, pred.residual(w), truth)
        for w in tqdm(RESIDUAL_WEIGHTS, desc="residual weights", unit="weight", disable=not progress)
    }


def calibrate_residual(
    model: BundleParts | Bundle,
    motion: dict[str, np.ndarray],
    frames: dict[str, np.ndarray],
    windows: list[tuple[str, int]] | None = None,
    max_windows: int | None = MAX_WINDOWS,
) -> dict:
    """The residual mode's calibration alone (:meth:`ModeErrors.residual_calibration`), on the
    windows :func:`window_mode_errors` uses: for a model trained before the residual mode."""
    _, m, truth = calibration_windows(motion, frames, model.codespace.config.window, windows, max_windows)
    pred = predict_windows(model.codespace, m, model.motion_stats, model.latent_stats, model.database)
    if pred.match_regression is None:
        raise ValueError("the database has no motion windows: the residual mode cannot run on this model")
    decode = model.autoencoder.inference_decoder()
    return choose_residual_weight(
        window_errors_mm(decode, pred.regression, truth), residual_errors(pred, decode, truth)
    )


def choose_residual_weight(
    regression_err: np.ndarray, residual_err: dict[float, np.ndarray], allowance: float = ACCURACY_ALLOWANCE
) -> dict:
    """The largest weight (0: regression) whose mean error is at most ``allowance`` x the
    regression's, its error, and every weight's."""
    errors = {0.0: float(np.mean(regression_err)), **{w: float(np.mean(e)) for w, e in residual_err.items()}}
    weight = max(w for w, e in errors.items() if w == 0.0 or e <= allowance * errors[0.0])
    return {
        "weight": weight,
        "validation_mm": errors[weight],
        "allowance": allowance,
        "errors_mm": {str(w): e for w, e in errors.items()},
    }


@dataclass
class TauSweep:
    """The hybrid's error and retrieval usage at each tau, and the best tau."""

    taus: list[float]
    errors_mm: list[float]
    retrieval_usage: list[float]  # fraction of windows retrieved
    best_tau: float

    def to_dict(self) -> dict:
        return {
            "taus": [t if math.isfinite(t) else "inf" for t in self.taus],
            "errors_mm": self.errors_mm,
            "retrieval_usage": self.retrieval_usage,
            "best_tau": self.best_tau,
        }


def sweep_tau(
    doubt: np.ndarray, regression_err: np.ndarray, retrieval_err: np.ndarray, steps: int = 20
) -> TauSweep:
    """Hybrid error for tau at 0, the doubt's quantiles and above its maximum (retrieval only, and a
    finite threshold a bundle can store: a window more doubtful than any seen regresses); picks the
    lowest."""
    quantiles = np.quantile(doubt, np.linspace(0, 1, steps + 1)) if len(doubt) else np.zeros(0)
    top = float(np.max(doubt)) + 1.0 if len(doubt) else math.inf
    taus = sorted({0.0, *[float(q) + 1e-6 for q in quantiles], top})
    errors, usage = [], []
    for tau in taus:
        retrieve = doubt < tau
        errors.append(float(np.where(retrieve, retrieval_err, regression_err).mean()))
        usage.append(float(retrieve.mean()))
    best = int(np.argmin(errors))  # first minimum: the smallest tau among ties
    return TauSweep(taus, errors, usage, taus[best])


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
        dataset_features(
            ds,
            names,
            bundle.codespace.config.memory,
            body_measures=bool(bundle.codespace.config.body_features),
        ),
        {n: body_frames(ds, [n]) for n in names},
        encoding=encoding,
    )
    return modes.summary(bundle.tau, bundle.gate)
