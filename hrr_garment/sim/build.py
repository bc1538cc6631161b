"""Resumable dataset building: simulate each planned sequence (in local worker processes or as Ray
tasks, :mod:`.executors`), keep each finished one as an atomic part file, then assemble the HDF5
dataset from the parts.

Parts live beside the dataset in ``NAME.parts/`` (:mod:`.parts`). Each records a key that hashes
the template, simulator settings and the sequence's spec; a re-run reuses parts whose key matches
and simulates the rest, so a killed build resumes where it stopped.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

from ..body.mannequin import MANNEQUIN, mannequin_record
from ..data.dataset import write_dataset
from ..data.splits import MIRROR_SUFFIX, mirror_source
from ..errors import InputError
from ..garment.dressing import DressedBody
from ..garment.mesh import GarmentMesh
from ..io_utils import atomic_write_text, exclusive_lock, strict_json
from ..motion.licences import OWN, SOURCES, licences_of
from .augment import (
    BACKWARD_PREFIX,
    SPLICE_PREFIX,
    STOP_PREFIX,
    SpliceSettings,
    plan_backward,
    plan_splices,
    plan_stops,
    splice_candidates,
    window_candidates,
)
from .build_split import split_finished
from .executors import EXECUTORS, Execution, batches, run_local, run_ray
from .motion_sources import spec_sources
from .parts import PART_VERSION, load_part, part_paths, parts_to_simulate, template_hash
from .plan import SequenceSpec
from .preset import MIRROR_MODES, mirror_mode
from .reflection import add_reflected_mirrors
from .simulator import SimSettings, SimulationExploded, simulate_garment
from .summary import summarise

# Renders a built dataset's preview image (records, garment, path, bodies=...) -> path or None;
# rendering lives above this layer (hrr_garment.export.preview.write_dataset_preview), so the
# caller passes it in.
PreviewWriter = Callable[..., "Path | None"]


@dataclass
class BuildReport:
    """What build_dataset did: the dataset, its sequences, rejects and summary."""

    path: Path
    sequences: list[str]
    rejects: dict[str, str]
    summary: dict
    reused: int = 0
    simulated: int = 0
    preview: Path | None = None
    stats: dict[str, dict] = field(default_factory=dict)


def warm_up(garment: GarmentMesh, config: SimSettings) -> None:
    """Compile/load the simulator's kernels once in this process (workers then find them cached)."""
    from ..motion.synth import synthesize

    clip = synthesize("idle", 0.1, seed=0)
    simulate_garment(garment, clip, replace(config, settle_s=0.0, blend_s=0.0))


@dataclass(frozen=True)
class BuildSettings:
    """How :func:`build_dataset` builds: what goes into the dataset (``splits``, ``seed``, ``groups``,
    ``kinds``, ``mirror``, ``info``: :func:`~hrr_garment.sim.plan.build_options` gives a preset's)
    and how the sequences are simulated (``jobs``, ``executor``, ``address``, ``retry_rejected``,
    ``progress``, ``preview``).

    ``groups`` (sequence name -> clip group) makes the split hold out whole groups; ``mirror`` adds
    every sequence mirrored left-right as ``NAME_mirror`` in its source's split: "simulate" simulates
    the mirrored motion (on the same body), "reflect" reflects the source's simulation (no solver
    time; a symmetric garment and body only, skipped with a note otherwise; not the mirrored
    motion's simulation where the solver has not converged, docs/dataset.md). ``executor``
    "ray" runs the pending sequences as Ray tasks (on the cluster at ``address``, or a local
    instance with ``jobs`` CPUs). ``retry_rejected`` simulates sequences that an earlier run
    rejected again (after a simulator change that may save them). ``kinds`` (sequence name ->
    motion kind, procedural clips) holds out only clips of kinds that also train
    (:func:`~hrr_garment.data.splits.split_names`). ``preview``: renders the dataset's preview image beside it
    (``hrr-simulate`` passes :func:`hrr_garment.export.preview.write_dataset_preview`).

    ``also_hold_out`` (field -> ``{"groups": {sequence name: group}, "val": v, "test": t}``) holds out
    whole groups of more fields beside ``groups`` (a sequence tests if any field's split tests it;
    sequences a field does not group train as far as that field goes).

    ``bodies`` (name -> a body and the garment on it, :mod:`.body_plan`) holds every body a sequence
    names (``SequenceSpec.body_name``); ``hold_out_bodies`` makes validation and test hold out whole
    bodies as well as whole groups (a sequence tests if its group or its body does).

    ``batch`` N simulates up to N sequences of similar length together, each in its own world of
    one newton model (:mod:`.batch`; for a GPU, ``SimSettings.device``): a worker process or Ray task
    per batch. 0 or 1 simulates one sequence per worker, as before. Parts and their keys are the
    same either way, so a batched build resumes an unbatched one and the other way round.

    ``splices`` (:mod:`.augment`) adds that many splices of the training clips (one's legs, another's
    upper body), drawn once the split is known, each checked for limbs through the body, and windows
    of training clips played backward and windows after which the body stops and stands, all
    training."""

    jobs: int | None = None
    splits: dict[str, float] | None = None
    seed: int = 0
    info: dict | None = None
    preview: PreviewWriter | None = None
    progress: bool = True
    groups: dict[str, str] | None = None
    mirror: str = ""  # "", "simulate" or "reflect" (sim.preset.mirror_mode reads a preset's)
    executor: str = "local"
    address: str | None = None
    retry_rejected: bool = False
    kinds: dict[str, str] | None = None
    bodies: dict[str, DressedBody] | None = None
    hold_out_bodies: bool = False
    # validation and test hold out whole cloths (SequenceSpec.material), or these cloths test
    hold_out_materials: bool | tuple[str, ...] = False
    batch: int = 0
    also_hold_out: dict[str, dict] | None = None
    splices: SpliceSettings | None = None
    # motion file -> its source (motion/licences.py; sim.plan.file_sources); files it lacks: the user's own
    file_sources: dict[str, str] | None = None
    # sequence -> "train", "val" or "test", drawn beforehand over a larger plan (a budget simulates a
    # subset of a library and keeps the library's held-out clips held out); None: drawn here
    assigned: dict[str, str] | None = None


def build_dataset(
    garment: GarmentMesh,
    specs: list[SequenceSpec],
    config: SimSettings,
    *,
    out: str | Path,
    options: BuildSettings = BuildSettings(),
) -> BuildReport:
    """Simulate what is missing, then write ``out`` (HDF5) atomically, as ``options`` say. See the
    module docstring and :class:`BuildSettings`."""
    o = options
    progress, executor = o.progress, o.executor
    if executor not in EXECUTORS:
        raise InputError(executor, f"unknown executor; choose one of {', '.join(EXECUTORS)}")
    mirror = mirror_mode(o.mirror)
    if mirror is None:
        raise InputError("mirror", f"{o.mirror!r} is not one of {', '.join(MIRROR_MODES)}")
    if mirror == "simulate":  # on the source's body, so that they split together
        specs = specs + [
            replace(s, name=f"{s.name}{MIRROR_SUFFIX}", mirrored=True) for s in specs if not s.mirrored
        ]
    out = Path(out)
    parts = out.with_suffix(".parts")
    parts.mkdir(parents=True, exist_ok=True)
    busy = "another hrr-simulate is building this dataset; wait for it, or write elsewhere with -o"
    with exclusive_lock(out.with_suffix(".lock"), out, busy):
        bodies = _check_bodies(specs, o.bodies or {})
        t0 = time.perf_counter()
        run = _simulate_missing(specs, garment, config, parts=parts, bodies=bodies, options=o)
        done = _finished(specs, run.rejects, parts)
        if not done:
            raise SimulationExploded(f"every sequence failed; nothing to write to {out}: {run.rejects}")
        split = split_finished(done, specs, o)
        splices, made, added = None, [], []
        if o.splices and o.splices.adds:  # drawn from the training clips once the split is known
            if progress:
                print(
                    f"planning {o.splices.count} splices of the training clips (each checked for limbs "
                    f"through the body), {o.splices.backward} windows played backward and "
                    f"{o.splices.stops} that stop and stand"
                )
            training = set(split["train"])
            splices = plan_splices(splice_candidates(specs, training, o.splices), o.splices)
            added = (
                splices.specs
                + plan_backward(window_candidates(specs, training, o.splices.seconds), o.splices)
                + plan_stops(window_candidates(specs, training, o.splices.stop_motion_s), o.splices)
            )
            spliced = _simulate_missing(added, garment, config, parts=parts, bodies=bodies, options=o)
            run = run.merged(spliced)
            made = _finished(added, spliced.rejects, parts)
            done += made
            split["train"] = sorted(split["train"] + made)
        sim_wall = time.perf_counter() - t0
        records = [load_part(part_paths(parts, n)[0], n) for n in done]
        summary = summarise(
            records,
            garment,
            rejects=run.rejects,
            sim_wall=sim_wall,
            jobs=run.jobs,
            simulated=run.simulated,
            bodies=bodies,
            cloth_of={x.name: x.material.name for x in specs + added if x.material is not None} or None,
        )
        if splices is not None:
            summary["splices"] = {
                "asked": o.splices.count,
                "made": sum(n.startswith(SPLICE_PREFIX) for n in made),
                "drawn": splices.drawn,
                "refused_self_intersection": splices.refused,
                "backward_asked": o.splices.backward,
                "backward_made": sum(n.startswith(BACKWARD_PREFIX) for n in made),
                "stops_asked": o.splices.stops,
                "stops_made": sum(n.startswith(STOP_PREFIX) for n in made),
            }
        if mirror == "reflect":
            records, split = add_reflected_mirrors(records, split, garment, progress=progress, bodies=bodies)
            summary["mirrored"] = len(records) - len(done)
        elif mirror == "simulate":
            summary["mirrored"] = sum(n.endswith(MIRROR_SUFFIX) for n in done)
        sources, summary["motion_licence"] = _motion_sources(specs + added, records, o.file_sources or {})
        write_dataset(
            out,
            garment,
            records,
            splits=split,
            info={**(o.info or {}), "summary": summary, "sim": config.to_dict(), **sources},
            bodies=bodies,
        )
        atomic_write_text(out.with_suffix(".summary.json"), strict_json(summary, indent=2))
        report = BuildReport(
            out,
            done,
            run.rejects,
            summary,
            run.reused,
            run.simulated - len(run.rejects),
            stats={r.name: r.info.get("stats", {}) for r in records},
        )
        if o.preview:
            report.preview = o.preview(records, garment, out.with_suffix(".preview.png"), bodies=bodies)
        return report


@dataclass
class _Simulated:
    """What one pass of :func:`_simulate_missing` did."""

    rejects: dict[str, str]
    reused: int
    simulated: int  # sequences it ran the simulator on (rejects included)
    jobs: int | None

    def merged(self, other: "_Simulated") -> "_Simulated":
        return _Simulated(
            {**self.rejects, **other.rejects},
            self.reused + other.reused,
            self.simulated + other.simulated,
            other.jobs if other.simulated else self.jobs,
        )


def _simulate_missing(
    specs: list[SequenceSpec],
    garment: GarmentMesh,
    config: SimSettings,
    *,
    parts: Path,
    bodies: dict[str, DressedBody],
    options: BuildSettings,
) -> _Simulated:
    """Simulate the ``specs`` that have no finished part under their key (parts of sibling datasets
    borrowed first), as ``options`` say (workers, Ray, batches, progress)."""
    o = options
    extra = {"template": template_hash(garment), "sim": config.to_dict(), "part_version": PART_VERSION}
    keys = {
        s.name: s.key({**extra, "body": bodies[s.body_name].key()} if s.body_name else extra) for s in specs
    }
    pending, rejects, reused = parts_to_simulate(specs, parts, keys, retry_rejected=o.retry_rejected)
    jobs = o.jobs
    if o.executor == "local":
        jobs = max(1, min(jobs or os.cpu_count() or 1, len(batches(pending, config, o.batch)) or 1))
    if pending:
        if o.progress:
            where = (
                ("in this process" if jobs == 1 else f"with {jobs} worker processes")  # executors.run_local
                if o.executor == "local"
                else f"on Ray ({o.address or f'local, {jobs or os.cpu_count()} CPUs'})"
            )
            where += f", batches of up to {o.batch} on {config.device}" if o.batch > 1 else ""
            print(
                f"simulating {len(pending)} of {len(specs)} sequences {where}; "
                f"{reused} already done (first run compiles kernels: about two minutes, cached after)"
            )
        warm_up(garment, config)
        everyone = {MANNEQUIN: DressedBody(MANNEQUIN, mannequin_record(), garment), **bodies}
        execution = Execution(keys, parts, jobs=jobs, progress=o.progress, batch=o.batch, address=o.address)
        run = run_ray if o.executor == "ray" else run_local
        rejects.update(run(pending, everyone, config, execution))
    return _Simulated(rejects, reused, len(pending), jobs)


def _motion_sources(specs: list[SequenceSpec], records: list, files: dict[str, str]) -> tuple[dict, dict]:
    """The dataset info's record of where each sequence's motion comes from (``motion_sources``) and
    those sources' terms (``sources``): motion/licences.py; and the summary's account of them. A
    reflected mirror is its source's."""
    by_name = {s.name: spec_sources(s, files) for s in specs}
    named = {r.name: by_name.get(r.name, by_name.get(mirror_source(r.name), OWN)) for r in records}
    used = {part for value in named.values() for part in value.split("+")}
    info = {"motion_sources": named, "sources": {k: SOURCES[k].to_dict() for k in sorted(used)}}
    return info, licences_of(named, info).to_dict()


def _finished(specs: list[SequenceSpec], rejects: dict[str, str], parts: Path) -> list[str]:
    """The names of ``specs`` with a finished part (in their order), rejects left out."""
    return [s.name for s in specs if s.name not in rejects and part_paths(parts, s.name)[0].exists()]


def _check_bodies(specs: list[SequenceSpec], bodies: dict[str, DressedBody]) -> dict[str, DressedBody]:
    missing = sorted({s.body_name for s in specs if s.body_name} - set(bodies))
    if missing:
        raise InputError("bodies", f"sequences name bodies that the build was not given: {missing[:5]}")
    return bodies
