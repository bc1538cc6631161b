"""The cross-source protocol: a model judged on clips from another motion source (another lab, rig
and capture pipeline) than it trained on, beside a model trained on that source.

    D=hrr_work/datasets M=hrr_work/models
    hrr-eval --model $M/dress-real-quick --split test --modes auto \\
        --other-source $D/dress-real-quick-commercial.h5=$M/dress-real-quick-commercial

Each ``--other-source`` names a dataset of the same garment whose motion comes from other sources
(its record of them: :mod:`hrr_garment.motion.licences`) and, optionally, the model trained on it
(the reference, which has seen its source). The protocol takes the captured clips of the
dataset's test split (procedural clips, the same generator on both sides, left out), leaves out
any clip the model itself trained on (a take shared by both libraries), keeps ``--sequences N`` of
the rest (evenly spaced), simulates each clip's truth ensemble and runs the model's default mode
(``auto``) and the reference's on the same clips: PVE / floor pooled and per clip, its worst clip,
the plausibility columns of :mod:`.unseen_bodies`, the model's ratio over the reference's and
(filled in by hrr-eval where the run also scored the model's own test split) over its own split's:
the gap between pipelines, on every model.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..data.dataset import GarmentDataset
from ..data.splits import mirror_source
from ..errors import InputError
from ..inference.animator import Animator
from ..inference.modes import Mode
from ..motion.licences import licences_of
from .ensemble_metrics import ensemble_ratios
from .evaluate import EvaluationSettings, evaluate_modes
from .mode_results import combine
from .protocols import truth_ensembles_of
from .unseen_bodies import DatasetAndModel, beside, evenly, over, scores_row, test_records


def trained_clips(animator: Animator) -> set[str]:
    """The clips (mirrors as their sources) the model trained or validated on, where its training
    dataset is still there; empty otherwise."""
    trained_on = Path(animator.bundle.manifest.dataset or "")
    if not trained_on.is_file():
        return set()
    ds = GarmentDataset(trained_on)
    return {mirror_source(n) for split in ("train", "val") for n in ds.splits.get(split, [])}


def _captured(records: list) -> list:
    """The records of captured motion (a motion file's sequences), procedural clips left out."""
    return [r for r in records if r.info.get("kind") == "file"]


def _scored(animator: Animator, records, settings: EvaluationSettings, ensembles: dict) -> dict:
    """The auto mode's row over ``records`` and each clip's PVE / floor."""
    result = evaluate_modes(animator, records, settings, ensembles=ensembles)[Mode.AUTO.value]
    clips = {
        name: entry["ensemble"].get("pve_floor_ratio")
        for name, entry in result.to_dict()["sequences"].items()
        if entry.get("ensemble")
    }
    worst = max(clips, key=lambda n: clips[n] or 0.0) if clips else None
    return {**scores_row(result), "clips": clips, "worst_clip": worst, "worst_pve_floor": clips.get(worst)}


def cross_source_section(
    animator: Animator,
    items: list[DatasetAndModel],
    settings: EvaluationSettings,
    sequences: int | None = None,
) -> dict:
    """report.json's ``cross_source``: per dataset, the model's and its reference's scores on its
    test clips (see the module docstring)."""
    auto = replace(settings, modes=(Mode.AUTO.value,))
    seen = trained_clips(animator)
    mine = sorted(animator.bundle.manifest.licences.sequences)
    out = {}
    for item in items:
        ds, records = test_records(item.dataset, animator, None)
        captured = _captured(records)  # procedural clips: the same generator on both sides
        shared = [r.name for r in captured if mirror_source(r.name) in seen]
        kept = {n: r for r in captured if (n := r.name) not in shared}
        records = [kept[n] for n in evenly(list(kept), sequences)]
        if not records:
            raise InputError(
                item.dataset, "has no test clip of captured motion that the model did not train on"
            )
        theirs = sorted(licences_of([r.name for r in records], ds.info).sequences)
        ensembles = truth_ensembles_of(
            ds, records, settings.members, jobs=settings.jobs, progress=settings.progress
        )
        entry = {
            "dataset": str(item.dataset),
            "model_sources": mine,  # empty where the model does not record them
            "clip_sources": theirs,  # empty where the dataset does not record them
            "left_out_trained": shared,
            "sequences": [r.name for r in records],
            "frames": int(sum(len(r.garment) for r in records)),
            "model": _scored(animator, records, auto, ensembles),
        }
        out[Path(item.dataset).stem] = beside(
            entry, item.model, "reference", score=lambda other: _scored(other, records, auto, ensembles)
        )
    return out


def captured_ratio(result, records) -> float | None:
    """A mode's pooled PVE / floor over the captured clips among ``records`` (the model's own test
    split, procedural clips left out as the protocol leaves them out), None without ensembles."""
    captured = {r.name for r in _captured(records)}
    rows = [s for s in result.sequences if s.name in captured and s.ensemble]
    if not rows:
        return None
    pooled = combine([s.ensemble for s in rows], [s.frames for s in rows])
    return ensemble_ratios(pooled).get("pve_floor_ratio")


def with_own_split(section: dict, own_ratio: float | None) -> dict:
    """``section`` with each dataset's PVE / floor over the model's own test split's (``own_ratio``,
    its auto mode's pooled ratio over that split's captured clips, :func:`captured_ratio`; None:
    not scored in this run)."""
    for entry in section.values():
        entry["own_split_pve_floor"] = own_ratio
        entry["pve_floor_over_own_split"] = over(entry["model"]["pve_floor_ratio"], own_ratio)
    return section


def markdown_table(section: dict) -> list[str]:
    """report.md's table of the protocol: a row per dataset, then each clip's ratio."""
    lines = [
        "| dataset | clips | frames | PVE / floor | over own split | worst clip | reference | "
        "over reference | inside seen before push-out % | sharpness | hem swing |",
        "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|",
    ]

    def num(value, digits: int = 2) -> str:
        return "-" if value is None else f"{value:.{digits}f}"

    clip_lines = []
    for name, e in section.items():
        m, r = e["model"], e.get("reference", {})
        worst = f"{m['worst_clip']} {num(m['worst_pve_floor'])}" if m.get("worst_clip") else "-"
        lines.append(
            f"| {name} | {len(e['sequences'])} | {e['frames']} | {num(m['pve_floor_ratio'])} | "
            f"{num(e.get('pve_floor_over_own_split'), 3)} | {worst} | {num(r.get('pve_floor_ratio'))} | "
            f"{num(e.get('pve_floor_over_reference'), 3)} | {num(m['inside_visible_before_pct'])} | "
            f"{num(m['bending_energy_ratio'])} | {num(m['hem_swing_ratio'])} |"
        )
        clip_lines += [
            f"| {name} | {clip} | {num(ratio)} | {num(r.get('clips', {}).get(clip))} |"
            for clip, ratio in m["clips"].items()
        ]
    if clip_lines:
        lines += ["", "| dataset | clip | PVE / floor | reference |", "|---|---|---:|---:|", *clip_lines]
    return lines
