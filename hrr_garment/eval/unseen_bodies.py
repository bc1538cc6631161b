"""The unseen-bodies protocol: a model trained across bodies, judged on bodies it never saw, beside
a specialist trained on each of those bodies alone.

    D=hrr_work/datasets M=hrr_work/models
    hrr-eval --model $M/dress-real-quick-bodies \\
        --unseen-body $D/dress-real-quick-short-heavy.h5=$M/dress-real-quick-short-heavy \\
        --unseen-body $D/dress-real-quick-tall-slim.h5=$M/dress-real-quick-tall-slim ...

Each ``--unseen-body`` names a dataset simulated on one body (``hrr-simulate --body``) and,
optionally, a model trained on that dataset alone (the specialist, the reference). The protocol
takes the dataset's test split (``--sequences N`` of it, evenly spaced), simulates each sequence's
truth ensemble on that body (its own floor), and runs the model's default mode (``auto``, each
model its own calibration) and the specialist's on the same clips. Per body: PVE / floor, the
cloth inside the body the viewer sees before the push-out (:mod:`.visible_inside`) and inside that
body's capsules, sharpness (bending energy over
the truth's) and hem swing (over the truth's), for both, and the generalist's PVE / floor over the
specialist's. A body the model was trained on is refused: the protocol is for bodies it never saw.

The unseen-materials protocol is the same with cloths for bodies (``--unseen-material``, ``kind``
"cloth"): each dataset simulated in one cloth (``hrr-simulate --material``), the model trained across
cloths (it animates each clip in the dataset's cloth) beside the specialist trained in that cloth
alone, a cloth the model was trained in refused, and one outside its range too.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..body.measures import body_vector
from ..data.dataset import DatasetError, GarmentDataset
from ..errors import InputError
from ..garment.material_range import material_vector
from ..inference.animator import Animator
from ..inference.modes import Mode
from .evaluate import EvaluationSettings, evaluate_modes
from .protocols import truth_ensembles_of
from .report_tables import SEEN, seen_cell

COLUMNS = (
    "pve_floor_ratio",
    "inside_visible_before_pct",
    "penetration_before_pct",
    "bending_energy_ratio",
    "hem_swing_ratio",
)


@dataclass(frozen=True)
class DatasetAndModel:
    """A protocol's dataset and, optionally, the model it is judged beside (an unseen body's
    specialist, another source's own model)."""

    dataset: Path
    model: Path | None = None

    @classmethod
    def parse(cls, text: str) -> "DatasetAndModel":
        """``DATASET`` or ``DATASET=MODEL_DIR`` (the command line's form)."""
        dataset, _, model = text.partition("=")
        return cls(Path(dataset), Path(model) if model else None)


def evenly(names: list[str], count: int | None) -> list[str]:
    """``count`` of ``names`` evenly spaced in their order (all of them without a count)."""
    if count is None or count >= len(names):
        return list(names)
    return [names[i] for i in sorted({int(round(i)) for i in np.linspace(0, len(names) - 1, count)})]


def test_records(dataset: Path, animator: Animator, sequences: int | None):
    """``dataset`` (of the model's garment, a DatasetError otherwise) and ``sequences`` of its test
    split, evenly spaced (all without a count), as records."""
    ds = GarmentDataset(dataset)
    if (
        ds.garment != animator.bundle.garment
        or ds.template.num_vertices != animator.bundle.template.num_vertices
    ):
        raise DatasetError(
            dataset,
            f"is a {ds.garment} dataset with {ds.template.num_vertices} vertices; the model "
            f"animates a {animator.bundle.garment} with {animator.bundle.template.num_vertices}",
        )
    names = evenly(ds.splits.get("test", []), sequences)
    if not names:
        raise DatasetError(dataset, "has no test sequences")
    return ds, [ds.sequence(n) for n in names]


class Held(NamedTuple):
    """What a protocol holds out, in words: a body or a cloth."""

    plural: str  # "bodies"
    on: str  # the preposition: "on" a body, "in" a cloth
    flag: str  # hrr-simulate's option that makes such a dataset


KINDS = {"body": Held("bodies", "on", "--body"), "cloth": Held("cloths", "in", "--material")}


def _held(record, kind: str) -> str:
    """The name of the body a record stands on, or of the cloth it was simulated in."""
    return record.body_name if kind == "body" else record.material.name


def _records(item: DatasetAndModel, animator: Animator, sequences: int | None, kind: str):
    ds, records = test_records(item.dataset, animator, sequences)
    held, words = {_held(r, kind) for r in records}, KINDS[kind]
    if len(held) != 1:
        raise DatasetError(
            item.dataset,
            f"its test sequences were simulated {words.on} {len(held)} {words.plural}; the protocol "
            f"takes a dataset simulated {words.on} one (hrr-simulate {words.flag})",
        )
    return ds, records


def _vector(kind: str, record) -> np.ndarray:
    """A record's body measures or cloth values."""
    return body_vector(record.dressed.record) if kind == "body" else material_vector(record.material)


def _trained(kind: str, training: GarmentDataset) -> dict[str, np.ndarray]:
    """The bodies (or cloths) of a dataset's training split by name, each's measures (or values)
    taken once."""
    out = {}
    for name in training.splits.get("train", []):
        if kind == "body":
            key = training.body_name_of[name]
            if key not in out:
                out[key] = body_vector(training.bodies[key].record)
        else:
            cloth = training.material_of(name)
            out.setdefault(cloth.name, material_vector(cloth))
    return out


def _check_unseen(animator: Animator, record, unseen: GarmentDataset, kind: str) -> None:
    """Refuse a body that one of the model's training sequences stood on, or a cloth one was
    simulated in (its training dataset's training split, where that dataset is still there); and,
    before any work, one outside the model's range (refused as a run would refuse it)."""
    from ..inference.run_material import run_material

    words, where = KINDS[kind], unseen.path
    if kind == "body":
        animator.body(record.dressed)
    else:
        run_material(animator.bundle, record.material, where=str(where))
    trained_on = Path(animator.bundle.manifest.dataset or "")
    if not trained_on.is_file():
        return
    training = GarmentDataset(trained_on)
    if kind == "cloth":
        _check_same_simulator(unseen, training)
    mine = _vector(kind, record)
    for name, theirs in sorted(_trained(kind, training).items()):
        if np.allclose(theirs, mine, atol=1e-4):
            raise InputError(
                where,
                f"was simulated {words.on} {kind} {name!r}, which the model was trained {words.on} "
                f"({trained_on}): the protocol is for {words.plural} it never saw",
            )


# simulator settings a cloth's dataset may hold apart from the model's training data: the cloth itself
# and where and how often it ran (the rest change the truth the cloth is scored against)
CLOTH_SETTINGS = ("material", "device", "retries")


def _check_same_simulator(unseen: GarmentDataset, training: GarmentDataset) -> None:
    """Refuse a cloth's dataset simulated otherwise than the model's training data (say, without the
    cloth's viscosity): the model would be scored against a truth of another solver."""
    ours, theirs = (
        {k: v for k, v in ds.info.get("sim", {}).items() if k not in CLOTH_SETTINGS}
        for ds in (unseen, training)
    )
    differ = sorted(k for k in ours.keys() | theirs.keys() if ours.get(k) != theirs.get(k))
    if differ:
        values = ", ".join(f"{k} {ours.get(k)} (the model's data: {theirs.get(k)})" for k in differ)
        raise InputError(
            unseen.path,
            f"was simulated with other simulator settings than the model's training data {training.path}: "
            f"{values}; simulate it as that data was, in its own cloth",
        )


def scores_row(result) -> dict:
    """A mode's result (:class:`~.mode_results.ModeResult`) as a protocol's row: its ensemble scores
    (:data:`COLUMNS`), the floor, the PVE and what its visible bodies were."""
    e = result.ensemble
    return {k: e.get(k) for k in COLUMNS} | {
        "floor_mm": e.get("floor_mm"),
        "pve_mm": result.metrics["pve_mm"],
        "visible_bodies": result.visible_bodies,
    }


def unseen_bodies_section(
    animator: Animator,
    bodies: list[DatasetAndModel],
    settings: EvaluationSettings,
    sequences: int | None = None,
    kind: str = "body",
) -> dict:
    """report.json's ``unseen_bodies`` (``kind`` "body") or ``unseen_materials`` ("cloth"): per body
    or cloth, the model's and its specialist's scores (see the module docstring)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    auto = replace(settings, modes=(Mode.AUTO.value,))
    out = {}
    for item in bodies:
        ds, records = _records(item, animator, sequences, kind)
        _check_unseen(animator, records[0], ds, kind)
        ensembles = truth_ensembles_of(
            ds, records, settings.members, jobs=settings.jobs, progress=settings.progress
        )
        entry = {
            "dataset": str(item.dataset),
            kind: _held(records[0], kind),
            "sequences": [r.name for r in records],
            "frames": int(sum(len(r.garment) for r in records)),
            "model": scores_row(
                evaluate_modes(animator, records, auto, ensembles=ensembles)[Mode.AUTO.value]
            ),
        }
        out[Path(item.dataset).stem] = beside(
            entry,
            item.model,
            "specialist",
            score=lambda other: scores_row(
                evaluate_modes(other, records, auto, ensembles=ensembles)[Mode.AUTO.value]
            ),
        )
    return out


def beside(entry: dict, model: Path | None, name: str, *, score) -> dict:
    """``entry`` with the model at ``model`` (where given) scored by ``score(animator)`` under
    ``name`` and ``entry``'s own model's PVE / floor over its (``pve_floor_over_NAME``)."""
    if model is None:
        return entry
    entry[name] = {"folder": str(model), **score(Animator.load(model))}
    entry[f"pve_floor_over_{name}"] = over(entry["model"]["pve_floor_ratio"], entry[name]["pve_floor_ratio"])
    return entry


def over(mine: float | None, theirs: float | None) -> float | None:
    """``mine / theirs``, None where either is unknown (or ``theirs`` 0)."""
    return mine / theirs if mine is not None and theirs else None


def markdown_table(section: dict, kind: str = "body") -> list[str]:
    """report.md's table of the protocol: a row per body (or cloth), the model beside its specialist."""
    lines = [
        f"| {kind} | frames | PVE / floor | specialist | ratio | inside seen before push-out % | "
        "specialist | capsules before push-out % | specialist | sharpness | specialist | hem swing | "
        "specialist |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]

    def f(row: dict, key: str, digits: int = 2) -> str:
        unknown = key in SEEN and key in row  # a figure inside a visible body that is unknown
        return "-" if row.get(key) is None and not unknown else seen_cell(row, key, digits)

    for name, e in section.items():
        m, s = e["model"], e.get("specialist", {})
        cells = [f(m, "pve_floor_ratio"), f(s, "pve_floor_ratio"), f(e, "pve_floor_over_specialist", 3)]
        for key in (
            "inside_visible_before_pct",
            "penetration_before_pct",
            "bending_energy_ratio",
            "hem_swing_ratio",
        ):
            cells += [f(m, key), f(s, key)]
        lines.append(f"| {name} | {e['frames']} | " + " | ".join(cells) + " |")
    return lines
