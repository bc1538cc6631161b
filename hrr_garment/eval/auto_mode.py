"""The ``auto`` mode's calibration: which of the hybrid, residual, detail and sample modes a model
runs by default, and how the detail mode runs.

Against a chaotic truth the most accurate output is close to the conditional mean, and the mean is
blurry: its folds and its hem's swing average away. The modes that use the database trade a little
accuracy for real simulated detail (docs/decisions/0009-auto-mode-default.md). ``auto`` is the calibrated
trade, chosen on the validation clips through the product path (``Animator.animate``: offline, blended,
push-out on) by one documented criterion that counts both:

1. accuracy first: the candidates whose PVE is within the allowance (``auto.allowance`` in the
   training configuration, :class:`AutoSettings`: 1.05, 5 %) of the most accurate candidate's. A
   sample of the truth's own distribution is about 1.4 x the PVE of its conditional mean, so cloth
   that looks like cloth costs PVE; 5 % of it for folds and swing that look real is the default's
   trade (issue 49's decision; it was 3 %). And no more cloth inside the body: a candidate may put
   at most ``auto.penetration_allowance`` (1.10) times the vertices inside the body (before the
   push-out) that the most accurate one does, or ``auto.penetration_floor_pct`` (1 %) of them where
   that is more (below it the push-out's work is small, and detail is not given up for it). Where
   the validation mixes the default body (the mannequin, which every command uses when given no
   body) with other bodies, the allowance holds on the default body's clips alone as well: on the
   bodies preset the trade averaged over its bodies cost the mannequin's clips 6.9 % at a 6 %
   allowance (docs/decisions/0035-auto-allowance-on-the-default-body.md). A
   match's swing, brought by the residual mode, is another simulation's cloth, on another body for
   a model across bodies: on the unseen short-heavy body it took the vertices inside from 3.0 to
   3.9 % (the folds alone to 3.3 %);
2. then plausibility: of those, the one whose cloth looks most like the simulation, i.e. the
   smallest *plausibility gap* ``hypot(ln sharpness, ln hem swing)``, sharpness being the bending
   energy over the truth's and hem swing the hem's amplitude over the truth's (0: both as in the
   simulation; a half and a double are equally far, and a gain in either counts);
3. ties: the cheaper mode (hybrid, then residual, then detail, then sample: the order of
   :data:`AUTO_CHOICES`), then the more accurate.

The sample mode (the generative decoder's draw, seed 0, where the model has it: ``hrr-train --stage
sampler``) is a candidate like the others, measured against the same one simulation per clip: a
draw is no nearer to it than the mean where the model is at the chaos floor, but a model short of
the floor can draw nearer (docs/sampler.md).

The detail mode is measured in several settings (:data:`DETAIL_CANDIDATES`): its simulated folds at
each of :data:`~.auto_criterion.DETAIL_STRENGTHS`, on the regression's latents and, where the residual mode
runs, on the residual mode's (which bring the match's swing). The folds' strength is the trade itself: on
held-out real clips the sharpness grows with it faster than the error
(docs/decisions/0005-detail-strength-calibrated.md). The criterion picks among all candidates; the detail
mode's setting is the picked one's, or, where auto is not a detail mode, the one the criterion picks among the
detail candidates alone (what ``--mode detail`` runs).

Every candidate that borrows from the matches (their residual, their folds) is also measured on
free cloth only (:data:`~hrr_garment.artifacts.free_cloth.FREE_CLOTH_RAMPS_MM`, labelled ``..., free
cloth 10-40 mm``): what it borrows weighted per region by how far it hangs from the body, so that
the skirt takes the match's swing and folds and the bodice keeps the regression's contact (a
match's are another simulation's, on another body for a model across bodies: on the unseen
tall-slim body the folds put 0.3 points more of the cloth inside). The model keeps one ramp for the
residual (``auto.residual_free_mm``): the picked candidate's where it uses the residual, else the
detail setting's where that does, else the one the criterion picks among the residual mode's; and
the detail setting's for the folds (``auto.folds_free_mm``).

Last, the first pick is measured again with the free cloth's swing restored at each of
:data:`~.auto_criterion.SWING_GAINS` (:mod:`hrr_garment.inference.swing`, labelled ``..., swing x1.2``) and
the criterion picks again among all candidates: a regression swings less than the cloth, so a gain
wins where it brings the swing closer to the truth's within the allowance. The model keeps the
picked candidate's gain (``auto.swing_gain``, 1 where the pick has none); it runs in the mode auto
picks, not in a mode named. A recorded calibration picked again under another allowance first
measures the gains of its new first pick where they were not (:func:`measure_again`), and a model
that gained the sample mode since has it measured first.

The criterion itself, on recorded numbers (:func:`~.auto_criterion.pick_auto_mode`,
:func:`~.auto_criterion.repick`), and the candidates' labels: :mod:`.auto_criterion`. Whether a
recorded calibration is out of date (calibrated again, or its gains measured first):
:mod:`.auto_outdated`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
from tqdm import tqdm

from ..artifacts.auto_calibration import AutoCalibration
from ..artifacts.bundle import Bundle
from ..artifacts.free_cloth import FREE_CLOTH_RAMPS_MM
from ..artifacts.manifest import AUTO_CHOICES
from ..artifacts.manifest_section import as_json, frozen
from ..body.mannequin import MANNEQUIN
from ..data.dataset import SequenceRecord
from ..garment.fit import hem_vertices
from ..inference.animator import Animator
from ..inference.fold_track import FOLD_FOLLOW
from ..inference.run_settings import DetailLook
from ..inference.swing import HALF_LIFE_S
from ..sim.quality import hem_swing
from . import metrics as M
from .auto_criterion import (
    DEFAULT_BODY_PVE,
    DETAIL_CANDIDATES,
    SWING_GAINS,
    AutoSettings,
    borrows,
    candidate_setting,
    free_cloth_label,
    pick_auto_mode,
    picked_fields,
    repick,
    swing_label,
    swing_of,
    uses_residual,
    without_swing,
)
from .scoring import as_simulated

AUTO_MAX_SEQUENCES = 24  # validation clips the choice animates at most (evenly spaced): about a minute


@contextmanager
def free_cloth(bundle: Bundle, ramp_mm: tuple[float, float] | None):
    """The bundle's residual and folds on free cloth with ``ramp_mm`` (None: everywhere) while the
    block runs: a calibration measuring its candidates (bundle.json ``auto.residual_free_mm`` and
    ``auto.folds_free_mm``, in memory only)."""
    before = bundle.manifest
    ramp = None if ramp_mm is None else tuple(ramp_mm)
    auto = replace(bundle.auto, residual_free_mm=ramp, folds_free_mm=ramp)
    bundle.manifest = replace(before, auto=auto)
    try:
        yield
    finally:
        bundle.manifest = before


def calibrate_auto_mode(
    animator: Animator,
    records: list[SequenceRecord],
    config: AutoSettings = AutoSettings(),
    max_sequences: int | None = AUTO_MAX_SEQUENCES,
    progress: bool = True,
) -> AutoCalibration:
    """Each candidate's PVE (mm, against each record's simulation), sharpness, hem swing and
    vertices inside the body before the push-out (%) on ``records`` (at most ``max_sequences`` of
    them, evenly spaced), and the mode the criterion picks under ``config``: the calibration
    bundle.json keeps under ``auto``, as it will hold it (the mode, the detail look, the criterion,
    the allowances (:meth:`AutoSettings.limits`), the clips and frames measured, ``fold_follow``: the
    folds' following in time the candidates ran with,
    :data:`~hrr_garment.inference.fold_track.FOLD_FOLLOW`, and ``candidates``: label -> numbers)."""
    records = _evenly(records, max_sequences)
    measure = _measurer(animator, records)
    bundle = animator.bundle
    residual = bundle.has_residual and bundle.residual_weight > 0
    labels = [m for m in AUTO_CHOICES if m != "detail" and animator.supports(m)]
    if animator.supports("detail"):
        labels += [
            label for label, (base, _) in DETAIL_CANDIDATES.items() if base == "regression" or residual
        ]
    labels += [
        free_cloth_label(label, ramp)
        for ramp in FREE_CLOTH_RAMPS_MM
        for label in labels
        if borrows(label) and (residual or not uses_residual(label))
    ]
    candidates = {
        label: measure(label) for label in tqdm(labels, desc="auto mode", unit="mode", disable=not progress)
    }
    _measure_swing(candidates, measure, config, progress)
    frames = sum(len(r.garment) for r in records)
    # as bundle.json will hold it (its keys in this order, a ramp not picked as null)
    return AutoCalibration.from_report(
        {
            "sequences": len(records),
            "frames": frames,
            "fold_follow": FOLD_FOLLOW,
            "folds_free_cloth": True,
            "default_body_sequences": sum(_on_default_body(bundle, records) or []),
            "swing_half_life_s": HALF_LIFE_S,
            "sampler_key": _sampler_key(bundle),
            "candidates": candidates,
            "criterion": "the most plausible (hypot(ln sharpness, ln hem swing)) within the allowance x the "
            "most accurate PVE and the penetration allowance x its cloth inside the body",
            **picked_fields(candidates, config, folds_free_cloth=True),
        },
        "auto",
    )


def measure_again(
    animator: Animator,
    records: list[SequenceRecord],
    auto: AutoCalibration,
    config: AutoSettings,
    *,
    new: tuple[str, ...] = (),
    max_sequences: int | None = AUTO_MAX_SEQUENCES,
    progress: bool = True,
) -> AutoCalibration:
    """A recorded calibration picked again under ``config``, the candidates ``new`` (a mode the model
    gained since: the sample mode's draw) and the swing gains of its new first pick measured on the
    same validation clips where they were not (the other candidates' numbers stand)."""
    # the recorded numbers as plain dicts (bundle.json's are read-only mappings, which JSON cannot
    # write), a new candidate's old ones (its swing gains too) left out
    candidates = {
        label: dict(numbers)
        for label, numbers in (auto.candidates or {}).items()
        if candidate_setting(label)[0] not in new
    }
    measure = _measurer(animator, _evenly(records, max_sequences))
    for label in tqdm(new, desc="auto mode", unit="mode", disable=not progress):
        candidates[label] = measure(label)
    _measure_swing(candidates, measure, config, progress)
    # the new numbers as bundle.json will hold them (a non-finite one as null), as the recorded ones are
    measured = replace(
        auto, candidates=frozen(as_json(candidates)), sampler_key=_sampler_key(animator.bundle)
    )
    return repick(measured, config)


def _sampler_key(bundle: Bundle) -> str | None:
    """The key of the generative decoder whose sample mode a calibration measures (None: none)."""
    return None if bundle.manifest.sampler is None else bundle.manifest.sampler.key


def _evenly(records: list[SequenceRecord], max_sequences: int | None) -> list[SequenceRecord]:
    if not records:
        raise ValueError("the auto mode is calibrated on validation sequences, and there are none")
    if max_sequences is not None and len(records) > max_sequences:
        records = [records[i] for i in np.linspace(0, len(records) - 1, max_sequences).round().astype(int)]
    return records


def _measure_swing(
    candidates: dict[str, Mapping[str, float]],
    measure: Callable[[str], dict[str, float]],
    config: AutoSettings,
    progress: bool,
) -> None:
    """The first pick (among the candidates without a gain) with its swing restored, each gain a
    candidate of its own, added to ``candidates`` where not there (the criterion then picks again
    among all: a gain wins where its swing closes the gap within the allowance)."""
    first = pick_auto_mode(without_swing(candidates), config)
    for gain in tqdm(SWING_GAINS, desc="swing gain", unit="gain", disable=not progress):
        if swing_label(first, gain) not in candidates:
            candidates[swing_label(first, gain)] = measure(swing_label(first, gain))


def _on_default_body(bundle: Bundle, records: list[SequenceRecord]) -> list[bool] | None:
    """Which of ``records`` stand on the model's default body, where they mix it with other bodies
    (None where they do not: a model of one body, or a validation without its default body)."""
    if not bundle.manifest.default_body_is_mannequin:
        return None  # a model of the one body it was trained on
    on = [r.body_name == MANNEQUIN for r in records]
    return on if any(on) and not all(on) else None


def _measurer(animator: Animator, records: list[SequenceRecord]) -> Callable[[str], dict[str, float]]:
    """A candidate's numbers on ``records`` by its label, animated through the product path (and
    its PVE on the default body's records alone, where they mix it with others)."""
    bundle = animator.bundle
    on_default = _on_default_body(bundle, records)
    template = bundle.template
    rest, topo = (
        template.vertices.astype(np.float64),
        M.MeshTopology.of(template.faces, template.num_vertices),
    )
    hem = hem_vertices(template)
    names = list(bundle.database.names)
    truths = [r.garment.astype(np.float64) for r in records]
    frames = sum(len(t) for t in truths)
    default_frames = sum(len(t) for t, on in zip(truths, on_default or []) if on)
    truth_bend = sum(float(M.cloth_energies(t, rest, topo)[1].sum()) for t in truths)
    truth_swing = sum(hem_swing(t, r.motion, hem) * len(t) for t, r in zip(truths, records))

    def measure(label: str) -> dict[str, float]:
        mode, base, strength, ramp = candidate_setting(label)
        look = DetailLook(base, strength) if mode == "detail" else DetailLook()
        error = bend = swing = inside = default_error = 0.0
        with free_cloth(bundle, ramp):
            for i, (r, truth) in enumerate(
                zip(records, truths)
            ):  # a clip in the database (the paper's validation) may not retrieve itself
                own = names.index(r.name) if r.name in names else None
                anim = animator.animate(
                    r.motion,
                    mode=mode,
                    detail=look,
                    swing=swing_of(label),
                    exclude_sequence=own,
                    **as_simulated(bundle, r),
                )
                pred = anim.vertices.astype(np.float64)
                inside += anim.penetration.inside_before * len(
                    pred
                )  # the product path pushes out: what it had to
                clip_error = M.pve_mm(pred, truth) * len(pred)
                error += clip_error
                default_error += clip_error if on_default and on_default[i] else 0.0
                bend += float(M.cloth_energies(pred, rest, topo)[1].sum())
                swing += hem_swing(pred, r.motion, hem) * len(pred)
        numbers = {
            "pve_mm": error / frames,
            "sharpness": bend / max(truth_bend, 1e-30),
            "hem_swing": swing / max(truth_swing, 1e-30),
            "penetration_pct": 100.0 * inside / frames,
        }
        if on_default:
            numbers[DEFAULT_BODY_PVE] = default_error / default_frames
        return numbers

    return measure
