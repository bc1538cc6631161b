"""Evaluate a model's modes on held-out sequences against simulated ground truth.

Every mode runs the product path (``Animator.animate``: offline windows blended per frame,
collision push-out unless disabled) on each sequence's motion, and every metric of
:mod:`.metrics` compares the world-space result with the simulated frames. Per-sequence values
are combined weighted by frame count (RMSE as the root of the weighted mean square, maxima as
maxima).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from ..body.capsules import DEFAULT_BODY, BodyModel
from ..data.dataset import SequenceRecord
from ..garment.fit import hem_vertices
from ..inference.animator import Animator
from ..inference.modes import Mode
from ..inference.run_settings import DetailLook, RunSettings
from ..sim.quality import body_signed_distance, penetration_fraction
from . import metrics as M
from .ensemble import TruthEnsemble
from .ensemble_metrics import ensemble_metrics, ensemble_ratios, truth_metrics


@dataclass
class SequenceResult:
    """One mode's metrics on one sequence, with its per-frame error, entropy and gate."""

    name: str
    frames: int
    metrics: dict[str, float]
    per_frame_pve_mm: np.ndarray  # (T,)
    entropy: np.ndarray  # (T,) motion-code entropy of the window centred on each frame
    retrieved: np.ndarray  # (T,) bool
    ensemble: dict[str, float] = field(default_factory=dict)  # against the truth ensemble, when there is one


@dataclass
class ModeResult:
    """One mode's results over every sequence; ``metrics`` weights them by frames."""

    mode: str
    tau: float
    sequences: list[SequenceResult] = field(default_factory=list)
    gate: str = "entropy"  # the hybrid's gate signal, which tau thresholds
    swing: float = 1.0  # the swing gain the mode ran with (inference/swing.py; auto: the calibrated one)

    @property
    def metrics(self) -> dict[str, float]:
        return combine([s.metrics for s in self.sequences], [s.frames for s in self.sequences])

    @property
    def ensemble(self) -> dict[str, float]:
        """Ensemble scores over the sequences that have a truth ensemble (empty when none has)."""
        rows = [s for s in self.sequences if s.ensemble]
        if not rows:
            return {}
        combined = combine([s.ensemble for s in rows], [s.frames for s in rows])
        return {**combined, **ensemble_ratios(combined), "sequences": len(rows)}

    def to_dict(self) -> dict:
        return {
            "mode": self.mode,
            "gate": self.gate,
            "tau": self.tau,
            "swing": self.swing,
            "metrics": self.metrics,
            "ensemble": self.ensemble,
            "sequences": {
                s.name: {
                    "frames": s.frames,
                    **s.metrics,
                    **({"ensemble": {**s.ensemble, **ensemble_ratios(s.ensemble)}} if s.ensemble else {}),
                }
                for s in self.sequences
            },
        }


MAXIMA = ("strain_max", "truth_strain_max", "penetration_before_worst_pct", "truth_penetration_worst_pct")


def combine(rows: list[dict[str, float]], weights: list[int]) -> dict[str, float]:
    """Frame-weighted means of per-sequence metrics (RMSE combined as a root mean square, the maximum
    strain as a maximum)."""
    w = np.asarray(weights, float) / max(sum(weights), 1)
    out = {}
    for key in rows[0]:
        values = np.array([r[key] for r in rows])
        if key == "rmse_mm":
            out[key] = float(np.sqrt((w * values**2).sum()))
        elif key in MAXIMA:
            out[key] = float(values.max())
        else:
            out[key] = float((w * values).sum())
    return out


def body_of(record: SequenceRecord) -> BodyModel:
    """The body a sequence was simulated on (its capsules): penetration is measured against it."""
    return record.dressed.body if record.dressed is not None else DEFAULT_BODY


def rest_of(record: SequenceRecord, template_rest: np.ndarray) -> np.ndarray:
    """The garment at rest on the sequence's body: strain and the cloth energies are measured from it."""
    return record.dressed.garment.vertices.astype(np.float64) if record.dressed is not None else template_rest


def sequence_metrics(
    pred: np.ndarray,
    truth: np.ndarray,
    record: SequenceRecord,
    rest: np.ndarray,
    topo: M.MeshTopology,
    retrieved: np.ndarray,
) -> dict[str, float]:
    """Every metric of one predicted sequence (world space, metres)."""
    pred, truth = pred.astype(np.float64), truth.astype(np.float64)
    out = {
        "pve_mm": M.pve_mm(pred, truth),
        "rmse_mm": M.rmse_mm(pred, truth),
        **M.sted(pred, truth, topo),
        "chamfer_cm": M.chamfer_cm(pred, truth),
        **M.penetration_pct(body_signed_distance(pred, record.motion, body_of(record))),
        "curvature_error_cm": M.curvature_error_cm(pred, truth, topo),
        **M.edge_strain_percentiles(pred, rest, topo),
        **M.energy_ratios(pred, truth, rest, topo=topo),
        **M.jitter_mm(pred, truth),
        "retrieval_usage": float(np.mean(retrieved)),
    }
    return out


def ensemble_truth(
    ensemble: TruthEnsemble,
    record: SequenceRecord,
    rest: np.ndarray,
    topo: M.MeshTopology,
    hem: np.ndarray | None,
) -> dict[str, float]:
    """The members' own values, the penetration and strain beside the floor and the other ``truth_*``."""
    truth_pen = [
        penetration_fraction(body_signed_distance(m, record.motion, body_of(record)))
        for m in ensemble.members
    ]
    strain = M.edge_strain_percentiles(ensemble.members.reshape(-1, *ensemble.members.shape[2:]), rest, topo)
    return {
        **truth_metrics(ensemble.members, record.motion, rest, topo=topo, hem=hem),
        "truth_penetration_pct": 100.0 * float(np.mean([p.mean() for p in truth_pen])),
        "truth_penetration_worst_pct": 100.0 * float(max(p.max() for p in truth_pen)),
        "truth_strain_p99": strain["strain_p99"],
        "truth_strain_max": strain["strain_max"],
    }


def sequence_ensemble_metrics(
    anim_vertices: np.ndarray,
    before_push_out: tuple[float, float] | None,
    ensemble: TruthEnsemble,
    record: SequenceRecord,
    rest: np.ndarray,
    topo: M.MeshTopology,
    hem: np.ndarray | None,
    truth: dict[str, float],
) -> dict[str, float]:
    """Ensemble scores of one prediction, with the penetration before the collision push-out
    (``before_push_out``: mean and worst-frame fraction; None when there was no push-out) and the
    members' own values (``truth``, from :func:`ensemble_truth`) beside it."""
    out = ensemble_metrics(
        anim_vertices, ensemble.members, record.motion, rest=rest, topo=topo, hem=hem, truth=truth
    )
    if before_push_out is None:
        pen = penetration_fraction(body_signed_distance(anim_vertices, record.motion, body_of(record)))
        before_push_out = float(pen.mean()), float(pen.max())
    out.update(
        penetration_before_pct=100.0 * before_push_out[0],
        penetration_before_worst_pct=100.0 * before_push_out[1],
    )
    return out


class _Scorer:
    """Scores predictions of one garment against records and their truth ensembles, the truths'
    own ensemble values computed once per record."""

    def __init__(self, template, ensembles: dict[str, TruthEnsemble] | None):
        self.topo = M.MeshTopology.of(template.faces, template.num_vertices)
        self.rest = template.vertices.astype(np.float64)
        self.hem = hem_vertices(template)
        self.ensembles = ensembles or {}
        self.truths: dict[str, dict[str, float]] = {}

    def sequence(
        self,
        vertices: np.ndarray,
        record: SequenceRecord,
        retrieved: np.ndarray,
        entropy: np.ndarray,
        before_push_out: tuple[float, float] | None,
    ) -> SequenceResult:
        ensemble, rest = {}, rest_of(record, self.rest)
        if record.name in self.ensembles:
            if record.name not in self.truths:
                self.truths[record.name] = ensemble_truth(
                    self.ensembles[record.name], record, rest, self.topo, self.hem
                )
            ensemble = sequence_ensemble_metrics(
                vertices,
                before_push_out,
                self.ensembles[record.name],
                record,
                rest,
                self.topo,
                self.hem,
                self.truths[record.name],
            )
        return SequenceResult(
            record.name,
            len(record.garment),
            sequence_metrics(vertices, record.garment, record, rest, self.topo, retrieved),
            M.per_frame_pve_mm(vertices.astype(np.float64), record.garment.astype(np.float64)),
            entropy,
            retrieved,
            ensemble,
        )


@dataclass(frozen=True)
class EvaluationSettings:
    """What an evaluation runs on every protocol: the modes, the run settings they share, the truths."""

    modes: tuple[str, ...]
    # the hybrid's gate and tau, the detail mode's look (used by that mode only) and the push-out;
    # its mode is each of ``modes`` in turn
    run: RunSettings = field(default_factory=RunSettings)
    exclude_own_sequence: bool = (
        False  # keep a record's own database sequence out of retrieval (the paper's comparison)
    )
    members: int = 0  # truth ensemble members per sequence (0: none)
    jobs: int | None = None  # simulation workers for the truths
    progress: bool = True

    def run_for(self, mode: str) -> RunSettings:
        """The run settings of ``mode``: the shared ones, the detail look only where it applies."""
        return self.run.replace(
            mode=mode, detail=self.run.detail if Mode(mode) is Mode.DETAIL else DetailLook()
        )


def _own_sequence(names: list[str], record: SequenceRecord, exclude: bool) -> int | None:
    """The record's own database sequence where it is one and ``exclude`` asks to keep it out."""
    return names.index(record.name) if exclude and record.name in names else None


def evaluate_modes(
    animator: Animator,
    records: list[SequenceRecord],
    settings: EvaluationSettings,
    ensembles: dict[str, TruthEnsemble] | None = None,
) -> dict[str, ModeResult]:
    """Each of ``settings.modes`` on each record, as ``settings`` ask. Records with a truth ensemble
    in ``ensembles`` are also scored against it."""
    bundle = animator.bundle
    scorer = _Scorer(bundle.template, ensembles)
    names = list(bundle.database.names)
    runs = {m: settings.run_for(m) for m in settings.modes}
    hybrid = animator.resolve(
        settings.run_for(Mode.HYBRID)
    )  # each mode's result records the hybrid's gate and tau
    results = {
        m: ModeResult(m, hybrid.tau, gate=hybrid.gate, swing=animator.resolve(runs[m]).swing)
        for m in settings.modes
    }
    jobs = [(m, r) for r in records for m in settings.modes]
    for mode, record in tqdm(jobs, desc="evaluate", unit="run", disable=not settings.progress):
        own = _own_sequence(names, record, settings.exclude_own_sequence)
        anim = animator.animate(
            record.motion, runs[mode], body=record.dressed, allow_outside=True, exclude_sequence=own
        )
        before = (anim.penetration.inside_before, anim.penetration.worst_before) if anim.penetration else None
        results[mode].sequences.append(
            scorer.sequence(
                anim.vertices, record, anim.retrieved.astype(bool), anim.entropy.astype(np.float64), before
            )
        )
    return results


def evaluate_vertices(
    label: str,
    predictions: dict[str, np.ndarray],
    records: list[SequenceRecord],
    template,
    ensembles: dict[str, TruthEnsemble] | None = None,
) -> ModeResult:
    """Given vertices (record name -> (T, V, 3) world) scored as a mode's would be, all of them
    counted as retrieved (a reference row: what a simulation of the right clip gives)."""
    result = ModeResult(label, math.nan)
    scorer = _Scorer(template, ensembles)
    for record in records:
        frames = len(record.garment)
        result.sequences.append(
            scorer.sequence(
                predictions[record.name], record, np.ones(frames, bool), np.full(frames, np.nan), None
            )
        )
    return result


@dataclass
class TauPoint:
    """The hybrid's error, retrieval usage and sharpness at one tau."""

    tau: float
    pve_mm: float
    retrieval_usage: float
    sharpness: float = float("nan")  # bending energy over the truth's (frames of every sequence together)


def tau_sweep(
    animator: Animator, records: list[SequenceRecord], taus: list[float], settings: EvaluationSettings
) -> list[TauPoint]:
    """Hybrid PVE, retrieval usage (fraction of frames) and sharpness at each tau of the settings'
    gate (default the model's), on the same records: accuracy and plausibility side by side."""
    names = list(animator.bundle.database.names)
    template = animator.bundle.template
    rest, topo = (
        template.vertices.astype(np.float64),
        M.MeshTopology.of(template.faces, template.num_vertices),
    )
    truth_bending = sum(
        float(M.cloth_energies(r.garment.astype(np.float64), rest, topo)[1].sum()) for r in records
    )
    hybrid = settings.run_for(Mode.HYBRID)
    points = []
    for tau in tqdm(taus, desc="tau sweep", unit="tau", disable=not settings.progress):
        errors, frames, retrieved, bending = 0.0, 0, 0, 0.0
        for record in records:
            own = _own_sequence(names, record, settings.exclude_own_sequence)
            anim = animator.animate(
                record.motion,
                hybrid.replace(tau=tau),
                body=record.dressed,
                allow_outside=True,
                exclude_sequence=own,
            )
            pred = anim.vertices.astype(np.float64)
            errors += M.pve_mm(pred, record.garment.astype(np.float64)) * len(anim.vertices)
            frames += len(anim.vertices)
            retrieved += int(anim.retrieved.sum())
            bending += float(M.cloth_energies(pred, rest, topo)[1].sum())
        points.append(
            TauPoint(float(tau), errors / frames, retrieved / frames, bending / max(truth_bending, 1e-30))
        )
    return points
