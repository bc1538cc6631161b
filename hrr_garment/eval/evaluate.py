"""Evaluate a model's modes on held-out sequences against simulated ground truth.

Every mode runs the product path (``Animator.animate``: offline windows blended per frame,
collision push-out unless disabled) on each sequence's motion, and every metric of
:mod:`.metrics` compares the world-space result with the simulated frames. Per-sequence values
are combined weighted by frame count (RMSE as the root of the weighted mean square, maxima as
maxima).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from ..data.dataset import SequenceRecord
from ..inference.animator import Animator
from ..inference.modes import Mode
from ..sim.quality import body_signed_distance
from . import metrics as M


@dataclass
class SequenceResult:
    """One mode's metrics on one sequence, with its per-frame error, entropy and gate."""

    name: str
    frames: int
    metrics: dict[str, float]
    per_frame_pve_mm: np.ndarray  # (T,)
    entropy: np.ndarray  # (T,) motion-code entropy of the window centred on each frame
    retrieved: np.ndarray  # (T,) bool


@dataclass
class ModeResult:
    """One mode's results over every sequence; ``metrics`` weights them by frames."""

    mode: str
    tau: float
    sequences: list[SequenceResult] = field(default_factory=list)

    @property
    def metrics(self) -> dict[str, float]:
        return combine([s.metrics for s in self.sequences], [s.frames for s in self.sequences])

    def to_dict(self) -> dict:
        return {"mode": self.mode, "tau": self.tau, "metrics": self.metrics,
                "sequences": {s.name: {"frames": s.frames, **s.metrics} for s in self.sequences}}


def combine(rows: list[dict[str, float]], weights: list[int]) -> dict[str, float]:
    """Frame-weighted means of per-sequence metrics (RMSE combined as a root mean square, the maximum
    strain as a maximum)."""
    w = np.asarray(weights, float) / max(sum(weights), 1)
    out = {}
    for key in rows[0]:
        values = np.array([r[key] for r in rows])
        if key == "rmse_mm":
            out[key] = float(np.sqrt((w * values ** 2).sum()))
        elif key == "strain_max":
            out[key] = float(values.max())
        else:
            out[key] = float((w * values).sum())
    return out


def sequence_metrics(pred: np.ndarray, truth: np.ndarray, record: SequenceRecord, rest: np.ndarray,
                     topo: M.MeshTopology, retrieved: np.ndarray) -> dict[str, float]:
    """Every metric of one predicted sequence (world space, metres)."""
    pred, truth = pred.astype(np.float64), truth.astype(np.float64)
    out = {"pve_mm": M.pve_mm(pred, truth), "rmse_mm": M.rmse_mm(pred, truth), **M.sted(pred, truth, topo),
           "chamfer_cm": M.chamfer_cm(pred, truth), **M.penetration_pct(body_signed_distance(pred, record.motion)),
           "curvature_error_cm": M.curvature_error_cm(pred, truth, topo),
           **M.edge_strain_percentiles(pred, rest, topo), **M.energy_ratios(pred, truth, rest, topo),
           **M.jitter_mm(pred, truth), "retrieval_usage": float(np.mean(retrieved))}
    return out


def evaluate_modes(animator: Animator, records: list[SequenceRecord], modes: list[str], tau: float | None = None,
                   exclude_own_sequence: bool = False, collision: bool = True, progress: bool = True) -> dict[str, ModeResult]:
    """Each mode on each record. ``exclude_own_sequence`` keeps a record's own database sequence
    (when it is one: training sequences) out of retrieval, as in the paper's comparison."""
    bundle = animator.bundle
    tau = bundle.tau if tau is None else float(tau)
    topo = M.MeshTopology.of(bundle.template.faces, bundle.template.num_vertices)
    rest = bundle.template.vertices.astype(np.float64)
    names = list(bundle.database.names)
    results = {m: ModeResult(m, tau) for m in modes}
    jobs = [(m, r) for r in records for m in modes]
    for mode, record in tqdm(jobs, desc="evaluate", unit="run", disable=not progress):
        own = names.index(record.name) if exclude_own_sequence and record.name in names else None
        anim = animator.animate(record.motion, mode=mode, tau=tau, collision=collision, exclude_sequence=own)
        results[mode].sequences.append(SequenceResult(
            record.name, len(record.garment),
            sequence_metrics(anim.vertices, record.garment, record, rest, topo, anim.mode.astype(bool)),
            M.per_frame_pve_mm(anim.vertices.astype(np.float64), record.garment.astype(np.float64)),
            anim.entropy.astype(np.float64), anim.mode.astype(bool)))
    return results


@dataclass
class TauPoint:
    """The hybrid's error and retrieval usage at one tau."""

    tau: float
    pve_mm: float
    retrieval_usage: float


def tau_sweep(animator: Animator, records: list[SequenceRecord], taus: list[float], exclude_own_sequence: bool = False,
              collision: bool = True, progress: bool = True) -> list[TauPoint]:
    """Hybrid PVE and retrieval usage (fraction of frames) at each tau, on the same records."""
    names = list(animator.bundle.database.names)
    points = []
    for tau in tqdm(taus, desc="tau sweep", unit="tau", disable=not progress):
        errors, frames, retrieved = 0.0, 0, 0
        for record in records:
            own = names.index(record.name) if exclude_own_sequence and record.name in names else None
            anim = animator.animate(record.motion, mode=Mode.HYBRID, tau=tau, collision=collision, exclude_sequence=own)
            errors += M.pve_mm(anim.vertices.astype(np.float64), record.garment.astype(np.float64)) * len(anim.vertices)
            frames += len(anim.vertices)
            retrieved += int(anim.mode.sum())
        points.append(TauPoint(float(tau), errors / frames, retrieved / frames))
    return points
