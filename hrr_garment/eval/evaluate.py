"""Evaluate a model's modes on held-out sequences against simulated ground truth.

Every mode runs the product path (``Animator.animate``: offline windows blended per frame,
collision push-out unless disabled) on each sequence's motion, and every metric of
:mod:`.metrics` compares the world-space result with the simulated frames. Per-sequence values
are combined weighted by frame count (RMSE as the root of the weighted mean square, maxima as
maxima). The results are in :mod:`.mode_results`, the scoring of a sequence in :mod:`.scoring`. The
frame path's world vertices before the push-out are kept too (:class:`StageOutput`): the cloth inside
the body the viewer sees is measured before and after it (:mod:`.visible_inside`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from ..data.dataset import SequenceRecord
from ..inference.animator import Animator
from ..inference.modes import Mode
from ..inference.run_settings import MAX_SEED, DetailLook, RunSettings
from . import metrics as M
from .ensemble import TruthEnsemble
from .mode_results import ModeResult
from .scoring import SequenceScorer, as_simulated


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
        """The run settings of ``mode``: the shared ones, the detail look and the sample mode's steps
        only where they apply."""
        return self.run.replace(
            mode=mode,
            detail=self.run.detail if Mode(mode) is Mode.DETAIL else DetailLook(),
            sample_steps=self.run.sample_steps if Mode(mode) is Mode.SAMPLE else None,
        )


class StageOutput:
    """An observer of the frame path (:class:`~hrr_garment.inference.frame_path.FramePath`) keeping a
    copy of one stage's output: the world vertices before the push-out, which the cloth inside the
    visible body is measured on too."""

    def __init__(self, stage: str):
        self.stage, self.value = stage, None

    def __call__(self, stage: str, value: np.ndarray) -> None:
        if stage == self.stage:
            self.value = np.array(value, copy=True)


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
    scorer = SequenceScorer(bundle.template, ensembles)
    names = list(bundle.database.names)
    runs = {m: settings.run_for(m) for m in settings.modes}
    hybrid = animator.resolve(
        settings.run_for(Mode.HYBRID)
    )  # each mode's result records the hybrid's gate and tau
    resolved = {m: animator.resolve(runs[m]) for m in settings.modes}
    results = {
        m: ModeResult(m, hybrid.tau, gate=hybrid.gate, swing=resolved[m].swing, settle=resolved[m].settle)
        for m in settings.modes
    }
    jobs = [(m, r) for r in records for m in settings.modes]
    for mode, record in tqdm(jobs, desc="evaluate", unit="run", disable=not settings.progress):
        own = _own_sequence(names, record, settings.exclude_own_sequence)
        world = StageOutput("world")
        run = runs[mode].replace(exclude_sequence=own, **as_simulated(bundle, record))
        anim = animator.animate(record.motion, run, observe=world)
        draws = None
        drawn = resolved[mode].mode is Mode.SAMPLE  # the sample mode, or auto calibrated to it
        if drawn and settings.members >= 2 and record.name in (ensembles or {}):
            # a sample is judged as a sample: as many draws as the truth has members, seeds on from the run's
            seeds = [(run.seed + k) % (MAX_SEED + 1) for k in range(1, settings.members)]
            draws = np.stack([animator.animate(record.motion, run.replace(seed=s)).vertices for s in seeds])
        results[mode].sequences.append(
            scorer.sequence(
                anim.vertices,
                record,
                anim.retrieved.astype(bool),
                anim.entropy.astype(np.float64),
                anim.penetration,
                unpushed=world.value,
                draws=draws,
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
    scorer = SequenceScorer(template, ensembles)
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
                exclude_sequence=own,
                **as_simulated(animator.bundle, record),
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
