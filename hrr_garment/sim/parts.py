"""One simulated sequence as a part file: computed anywhere, written by whoever holds the folder.

A part is ``<sequence>.npz`` (arrays only, no pickle) or ``<sequence>.failed.json`` for a sequence
that exploded on every attempt, each with a key that hashes the template, simulator settings and
the sequence's spec. :func:`simulate_sequence` computes a part's content from a motion (in a local
worker or a Ray task on another machine), :func:`simulate_sequences` the parts of a batch of
sequences simulated together (:mod:`.batch`); :func:`write_part` writes it atomically, so the same
bytes land whichever executor ran it. The key does not depend on batching: a batched build resumes
an unbatched one and the other way round. :func:`parts_to_simulate` says which sequences of a build
still need the simulator, after :func:`borrow_part` has taken what a sibling dataset in the same
folder simulated under the same key.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel
from ..body.mannequin import MANNEQUIN
from ..body.mesh_collider import SkinnedPieces, skinned_pieces
from ..body.retarget import motion_on_body
from ..data.dataset import SequenceRecord
from ..garment.dressing import DressedBody
from ..garment.mesh import GarmentMesh
from ..io_utils import atomic_path, atomic_write_text
from ..motion.motion import Motion
from ..motion.skeleton import Skeleton
from .batch import BatchItem, simulate_batch
from .plan import SequenceSpec
from .quality import sequence_stats
from .simulator import SimResult, SimSettings, SimulationExploded, simulate_garment

PART_VERSION = 1


def template_hash(mesh: GarmentMesh) -> str:
    """A short hash of the template's vertices, faces and attached vertices."""
    h = hashlib.sha1()
    for arr in (mesh.vertices, mesh.faces, mesh.attached):
        h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()[:16]


def part_paths(parts: Path, name: str) -> tuple[Path, Path]:
    """A sequence's part file and its failure note."""
    return parts / f"{name}.npz", parts / f"{name}.failed.json"


def read_part_key(part: Path) -> str | None:
    """The settings key a part was made under, or None for an unreadable part."""
    try:
        with np.load(part, allow_pickle=False) as z:
            return str(z["key"])
    except (OSError, KeyError, ValueError):
        return None  # unreadable or from an older layout: simulate again


@dataclass
class PartResult:
    """What one simulation produced: the recorded frames and their statistics, or why it failed."""

    name: str
    key: str
    frames: int  # simulated frames, lead-in included (for progress)
    vertices: np.ndarray | None = None
    motion: Motion | None = None
    info: dict | None = None
    failure: str | None = None


@dataclass(frozen=True)
class SequenceJob:
    """One sequence to simulate: its spec, its motion (``spec.motion()``; None until it is loaded
    where the job runs), the garment (the template on the mannequin), its part's key and its body
    (:mod:`.body_plan`; None: the mannequin)."""

    spec: SequenceSpec
    motion: Motion | None
    garment: GarmentMesh
    key: str
    body: DressedBody | None = None

    def on_body(self) -> tuple[Motion, GarmentMesh, BodyModel]:
        """The motion as the body plays it, the garment on the body and the body's capsules."""
        if self.body is None:
            return self.motion, self.garment, DEFAULT_BODY
        return motion_on_body(self.motion, self.body.body), self.body.garment, self.body.body

    def collider(self) -> SkinnedPieces | None:
        """What the cloth collides with where the body has a mesh of its own (its skinned mesh in
        pieces); None: the capsules (the mannequin, drawn as its capsules)."""
        visible = None if self.body is None else self.body.visible
        return None if visible is None else skinned_pieces(self.body.body, visible)


def _part(
    job: SequenceJob, on_body: tuple[Motion, GarmentMesh, BodyModel], result: SimResult | SimulationExploded
) -> PartResult:
    """A part's content from a simulation's result (or its rejection), with the sequence's
    statistics; ``on_body``: what :meth:`SequenceJob.on_body` gave the simulation."""
    spec = job.spec
    if isinstance(result, SimulationExploded):
        return PartResult(spec.name, job.key, 0, failure=str(result))
    motion, garment, capsules = on_body
    stats = sequence_stats(
        result.vertices,
        garment.vertices,
        garment.edges(),
        motion=motion,
        hem=garment.groups.get("hem"),
        body=capsules,
        visible=None if job.body is None else job.body.visible,
    )
    stats.update(
        substeps=result.substeps,
        attempts=result.attempts,
        sim_seconds=result.seconds,
        simulated_frames=result.simulated_frames,
        arms_off_frames=result.arms_off_frames,
    )
    info = {"kind": spec.kind, "seed": spec.seed, "path": spec.path, "stats": stats}
    if job.body is not None:
        info["body_name"] = job.body.name
    if spec.material is not None:
        info["material"] = spec.material.to_dict()
    return PartResult(spec.name, job.key, result.simulated_frames, result.vertices, motion, info)


def in_cloth(settings: SimSettings, spec: SequenceSpec) -> SimSettings:
    """The build's simulator ``settings`` in the sequence's own cloth, where it names one."""
    return settings if spec.material is None else replace(settings, material=spec.material)


def simulate_sequence(
    spec: SequenceSpec,
    motion: Motion,
    garment: GarmentMesh,
    config: dict,
    key: str,
    progress: Callable[[int], None] | None = None,
    body: DressedBody | None = None,
) -> PartResult:
    """Simulate one sequence (``motion`` is ``spec.motion()``, loaded by the caller) on the
    mannequin, or on ``body`` (the sequence's, :mod:`.body_plan`): the motion played by that body
    (:func:`~hrr_garment.body.retarget.motion_on_body`) and the garment on it."""
    job = SequenceJob(spec, motion, garment, key, body)
    played, dressed, capsules = on_body = job.on_body()
    try:
        result = simulate_garment(
            dressed,
            played,
            in_cloth(SimSettings.from_dict(config), spec),
            body=capsules,
            progress=progress,
            collider=job.collider(),
        )
    except SimulationExploded as exc:
        result = exc
    return _part(job, on_body, result)


def simulate_sequences(
    jobs: list[SequenceJob], config: dict, progress: Callable[[int], None] | None = None
) -> list[PartResult]:
    """Simulate ``jobs`` as one batch (:func:`~.batch.simulate_batch`: one model, each sequence in
    its own world); each part is what :func:`simulate_sequence` makes of it alone, within the
    solver's tolerance, and one that explodes in the batch is simulated alone with every retry."""
    on_bodies = [job.on_body() for job in jobs]
    items = [
        BatchItem(garment, motion, body, collider=job.collider())
        for job, (motion, garment, body) in zip(jobs, on_bodies)
    ]
    cloths = {job.spec.material for job in jobs}
    if len(cloths) > 1:  # a batch is one model of one cloth (executors.batches groups by cloth)
        raise ValueError(f"a batch of sequences in {len(cloths)} cloths; batch each cloth's apart")
    results = simulate_batch(items, in_cloth(SimSettings.from_dict(config), jobs[0].spec), progress=progress)
    return [_part(job, on_body, result) for job, on_body, result in zip(jobs, on_bodies, results)]


def write_part(result: PartResult, parts: Path) -> None:
    """Write a part (or its failure record) atomically into ``parts``."""
    part, failed = part_paths(parts, result.name)
    if result.failure is not None:
        atomic_write_text(
            failed, json.dumps({"key": result.key, "name": result.name, "reason": result.failure})
        )
        return
    motion = result.motion
    failed.unlink(missing_ok=True)  # an earlier rejection that a retry has now saved
    on_body = (
        {"skeleton_offsets": np.asarray(motion.skeleton.offsets, np.float32)}
        if "body_name" in result.info
        else {}
    )
    with atomic_path(part) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(
                fh,
                key=np.array(result.key),
                garment=result.vertices,
                local_rotations=motion.local_rotations,
                root_translation=motion.root_translation,
                fps=np.array(motion.fps),
                source=np.array(motion.source),
                info=np.array(json.dumps(result.info)),
                **on_body,
            )


def load_part(part: Path, name: str) -> SequenceRecord:
    """A finished part as a SequenceRecord."""
    with np.load(part, allow_pickle=False) as z:
        info = json.loads(str(z["info"]))
        if "body" in info:  # a part written before the body's name was called body_name (same key)
            info["body_name"] = info.pop("body")
        on_body = {"skeleton": Skeleton(offsets=z["skeleton_offsets"])} if "skeleton_offsets" in z else {}
        motion = Motion(
            z["local_rotations"], z["root_translation"], float(z["fps"]), source=str(z["source"]), **on_body
        )
        return SequenceRecord(
            name, z["garment"], motion, info=info, body_name=info.get("body_name", MANNEQUIN)
        )


def parts_to_simulate(
    specs: list[SequenceSpec], parts: Path, keys: dict[str, str], *, retry_rejected: bool
) -> tuple[list[SequenceSpec], dict[str, str], int]:
    """(the sequences to simulate, the rejects an earlier run recorded under the same key and
    that stay rejected, how many finished parts are reused)."""
    pending, rejects, reused = [], {}, 0
    siblings = [p for p in sorted(parts.parent.glob("*.parts")) if p != parts]
    for spec in specs:
        part, failed = part_paths(parts, spec.name)
        if siblings and not (part.exists() and read_part_key(part) == keys[spec.name]):
            borrow_part(part, keys[spec.name], siblings)
        if part.exists() and read_part_key(part) == keys[spec.name]:
            reused += 1
        elif (
            not retry_rejected
            and failed.exists()
            and json.loads(failed.read_text()).get("key") == keys[spec.name]
        ):
            rejects[spec.name] = json.loads(failed.read_text())["reason"]
        else:
            pending.append(spec)
    return pending, rejects, reused


def borrow_part(part: Path, key: str, siblings: list[Path]) -> None:
    """Reuse the same sequence's part from another dataset in the same folder (``siblings``: their
    ``*.parts`` folders) when it was simulated under the same key (template, settings, motion): a
    preset that only splits the same clips otherwise (``also_hold_out``) simulates nothing again.
    Hard-linked where the file system allows, else copied (atomically: a temporary name, then a
    rename)."""
    for sibling in siblings:
        other = sibling / part.name
        if not other.exists() or read_part_key(other) != key:
            continue
        temporary = part.with_name(f".{part.name}.borrowed")
        temporary.unlink(missing_ok=True)
        try:
            os.link(other, temporary)
        except OSError:
            shutil.copyfile(other, temporary)
        os.replace(temporary, part)
        return
