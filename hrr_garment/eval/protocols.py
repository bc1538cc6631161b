"""hrr-eval's protocols beyond the dataset's own split (docs/evaluation.md): real motion files, the
game's clip library played again, the paper's protocol, each simulated for its ground truth with the
dataset's settings (cached under the workspace) and, with truth ensembles, against the chaos floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..body.mannequin import MANNEQUIN
from ..errors import InputError
from ..inference.run_settings import DetailLook, RunSettings
from .evaluate import EvaluationSettings, evaluate_modes, evaluate_vertices, tau_sweep
from .scoring import as_simulated


def default_taus(animator, records, run: RunSettings) -> list[float]:
    """0, the deciles of the hybrid gate's per-frame doubts on these records (``run``'s gate, default
    the model's), and above the maximum (retrieval only)."""
    hybrid = run.replace(mode="hybrid", tau=0.0, push_out=False, detail=DetailLook())
    h = np.concatenate(
        [animator.animate(r.motion, hybrid, **as_simulated(animator.bundle, r)).doubt for r in records]
    )
    top = float(h.max()) + 1e-3 if len(h) else 1.0
    if animator.resolve(hybrid).gate == "entropy":  # at least every entropy
        top = max(top, math.log(animator.bundle.codespace.config.classes) + 1e-3)
    return sorted(
        {0.0, *[round(float(q), 4) for q in np.quantile(h, np.linspace(0.1, 0.9, 9))], round(top + 5e-5, 4)}
    )


def truth_ensembles_of(ds, records, members: int, jobs: int | None, progress: bool) -> dict:
    """The truth ensembles of ``records`` (none when ``members`` is 0 or the dataset was not simulated)."""
    if not members:
        return {}
    if "sim" not in ds.info:
        print(
            f"{ds.path} records no simulator settings (not built by hrr-simulate): no ensemble ground truth"
        )
        return {}
    from ..sim.simulator import SimSettings
    from .ensemble import truth_ensembles

    return truth_ensembles(
        ds.template,
        records,
        SimSettings.from_dict(ds.info["sim"]),
        members=members,
        jobs=jobs,
        progress=progress,
        bodies=ds.bodies,
    )


def ensemble_summary(ensembles: dict, records, members: int) -> dict:
    """What report.json records about the truth ensembles."""
    if not ensembles:
        return {"members": 0}
    first = next(iter(ensembles.values()))
    return {
        "members": members,
        "perturbations": first.perturbations,
        "sequences": len(ensembles),
        "without_ensemble": [r.name for r in records if r.name not in ensembles],
        "failed_members": {name: e.failed for name, e in ensembles.items() if e.failed},
    }


@dataclass(frozen=True)
class SimulatedTruth:
    """Sequences whose ground truth an evaluation simulates: their specs, the dataset file to
    simulate them into (parts cached beside it) and what the file is for."""

    specs: list
    path: Path
    purpose: str


@dataclass(frozen=True)
class LibraryPlays:
    """The library protocol's request: ``count`` plays drawn with ``seed``; its own tau sweep
    (``sweep``) at ``taus`` (default: :func:`default_taus`)."""

    count: int
    seed: int = 0
    taus: list[float] | None = None
    sweep: bool = True


def own_body(ds):
    """The one body a dataset's sequences were all simulated on, where it is not the mannequin (a
    character's, an anny body's): the body a simulated protocol's truths stand on, so that the model
    is judged on its own body (None: the mannequin, as for a dataset across bodies, whose default
    body it is)."""
    names = {ds.body_name_of[n] for n in ds.names}
    if len(names) != 1 or MANNEQUIN in names:
        return None
    return ds.bodies[names.pop()]


def simulated_section(
    animator, ds, truth: SimulatedTruth, settings: EvaluationSettings
) -> tuple[dict, list, dict]:
    """Simulate the ground truth of ``truth`` with the dataset's settings (parts cached) and
    evaluate every mode there: the report section, the records and their truth ensembles."""
    from ..data.dataset import GarmentDataset
    from ..sim.build import BuildSettings, build_dataset
    from ..sim.simulator import SimSettings

    config = SimSettings.from_dict(ds.info.get("sim", {}))
    body = own_body(ds)
    specs = truth.specs if body is None else [replace(s, body_name=body.name) for s in truth.specs]
    print(
        f"simulating ground truth for {len(specs)} sequence(s) on "
        f"{'the mannequin' if body is None else f'the body {body.name!r}'} (cached in "
        f"{truth.path.with_suffix('.parts')})"
    )
    report = build_dataset(
        ds.template,
        specs,
        config,
        out=truth.path,
        options=BuildSettings(
            splits={"val": 0.0, "test": 0.0},
            info={"purpose": truth.purpose, "source_dataset": str(ds.path)},
            progress=settings.progress,
            bodies=None if body is None else {body.name: body},
        ),
    )
    data = GarmentDataset(report.path)
    records = [data.sequence(n) for n in report.sequences]
    ensembles = truth_ensembles_of(data, records, settings.members, settings.jobs, settings.progress)
    results = evaluate_modes(animator, records, settings, ensembles=ensembles)
    return (
        {
            "dataset": str(report.path),
            "sequences": report.sequences,
            "frames": int(sum(len(r.garment) for r in records)),
            "rejected": report.rejects,
            "ensemble": ensemble_summary(ensembles, records, settings.members),
            "modes": {m: r.to_dict() for m, r in results.items()},
        },
        records,
        ensembles,
    )


def real_motion_section(
    animator, ds, files: list[str], settings: EvaluationSettings, source_fps: float | None = None
) -> dict:
    """The real motion files' section: their ground truth simulated with the dataset's settings."""
    from ..paths import workspace
    from ..sim.plan import plan_sequences
    from ..sim.preset import load_preset

    specs = plan_sequences(
        load_preset(str(ds.info.get("preset", "quick"))), motions=list(files), source_fps=source_fps
    )
    truth = SimulatedTruth(
        specs, workspace() / "eval" / f"{ds.path.stem}-real-motion.h5", "hrr-eval real motion"
    )
    section, _, _ = simulated_section(animator, ds, truth, settings)
    return {"files": [str(f) for f in files], **section}


def paper_section(folder: Path, bundle, records, settings: EvaluationSettings, ensembles: dict) -> dict:
    """The paper protocol's section: a model whose code space was validated on a tenth of its
    training clips' windows, on the same sequences, with its goals beside the paper's ratios (its
    own calibrated gate and tau)."""
    from ..inference.animator import Animator, find_model
    from .goals import PAPER_RATIOS, goals

    folder = find_model(folder)
    animator = Animator.load(folder)
    other = animator.bundle
    if other.manifest.validation != "windows":
        raise InputError(
            folder,
            "was validated on held-out clips; the paper protocol needs a model trained with "
            "hrr-train --validation windows",
        )
    if other.garment != bundle.garment or other.template.num_vertices != bundle.template.num_vertices:
        raise InputError(
            folder,
            f"is a {other.garment} model with {other.template.num_vertices} vertices; the evaluated "
            f"one is {bundle.garment} with {bundle.template.num_vertices}",
        )
    modes = tuple(m for m in settings.modes if animator.supports(m))
    print(
        f"paper protocol: {folder} (calibrated gate {other.gate} < {other.tau:.3f}) on the same "
        f"{len(records)} sequences"
    )
    own = replace(
        settings, modes=modes, exclude_own_sequence=False, run=RunSettings(push_out=settings.run.push_out)
    )  # its own calibrated gate, tau and look
    results = evaluate_modes(animator, records, own, ensembles=ensembles)
    return {
        "model": str(folder),
        "hash": other.content_hash,
        "gate": other.gate,
        "tau": other.tau,
        "modes": {m: r.to_dict() for m, r in results.items()},
        "goals": goals(results, None),
        "paper_ratios": PAPER_RATIOS,
    }


def library_section(animator, ds, plays_asked: LibraryPlays, settings: EvaluationSettings) -> dict | None:
    """The library protocol's section (docs/evaluation.md): plays of the clips in the model's
    database, simulated and evaluated, with their own tau sweep and goals."""
    from ..paths import workspace
    from ..sim.plan import SequenceSpec
    from .goals import library_goals
    from .library import SOURCE_SIMULATION, library_plays, plays_digest, save_plays, source_simulation

    if "sim" not in ds.info:
        print(f"{ds.path} records no simulator settings (not built by hrr-simulate): no library protocol")
        return None
    names = [n for n in animator.bundle.database.names if n in ds.frames]
    plays = library_plays(ds, names, plays_asked.count, seed=plays_asked.seed)
    folder = workspace() / "eval" / "library" / f"{ds.path.stem}-{plays_digest(plays)}"
    files = save_plays(plays, folder)
    print(f"library protocol: {plays_asked.count} plays of the database's clips (motions in {folder})")
    specs = [
        SequenceSpec(p.name, "file", path=str(f), start=0, stop=p.motion.num_frames)
        for p, f in zip(plays, files)
    ]
    settings = replace(settings, exclude_own_sequence=False)
    section, records, ensembles = simulated_section(
        animator, ds, SimulatedTruth(specs, folder / "truth.h5", "hrr-eval library protocol"), settings
    )
    by_name = {p.name: p for p in plays}
    reference = evaluate_vertices(
        SOURCE_SIMULATION,
        {r.name: source_simulation(ds, by_name[r.name]) for r in records},
        records,
        template=animator.bundle.template,
        ensembles=ensembles,
    )
    points = None
    if plays_asked.sweep and records:
        points = tau_sweep(
            animator,
            records,
            plays_asked.taus or default_taus(animator, records, settings.run),
            settings=settings,
        )
    section.update(
        plays={p.name: p.description for p in plays},
        seed=plays_asked.seed,
        source_simulation=reference.to_dict(),
        tau_sweep=[vars(p) for p in points or []],
        goals=library_goals(section["modes"], points),
    )
    return section
