"""Ensemble ground truth: K perturbed re-simulations of each evaluated sequence (docs/method.md).

Cloth simulation is chaotic: the same motion simulated with the density changed by one part in
10,000 ends 15-25 mm PVE away from the first run, so a single simulated truth cannot rank models
below that. Each evaluated sequence is therefore simulated again K times (default 4), each
member with one small perturbation of the dataset's own simulator settings:

    member 0: density x (1 + 1e-4)      member 1: density x (1 - 1e-4)
    member 2: settle one frame longer   member 3: settle one frame shorter
    members 4-7: the same at twice the size, and so on.

The dataset's recorded frames are not a member: every member is perturbed alike, so none is
privileged. Members are cached one file each under ``$HRR_HOME/cache/ensemble`` (keyed by the
template, the motion and the settings), so an interrupted or repeated evaluation simulates only
what is missing, and every model evaluated on the same data shares them. A member whose
simulation explodes is left out (and reported); a sequence needs two members for a floor.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator
from concurrent.futures import as_completed
from contextlib import closing
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from ..body.capsules import DEFAULT_BODY, BodyModel
from ..body.mannequin import MANNEQUIN
from ..body.mesh_collider import skinned_pieces
from ..body.skinned_body import SkinnedBody
from ..data.dataset import SequenceRecord
from ..garment.dressing import DressedBody
from ..garment.material import material_from
from ..garment.mesh import GarmentMesh
from ..io_utils import atomic_path, atomic_write_text
from ..paths import workspace
from ..sim.parts import template_hash
from ..sim.simulator import SimSettings, SimulationExploded, simulate_garment
from ..workers import spawned_pool

DENSITY_STEP = 1.0e-4
ENSEMBLE_VERSION = 1


def member_config(config: SimSettings, k: int, fps: float) -> tuple[SimSettings, str]:
    """The settings of member ``k`` and a short description of its perturbation."""
    size, kind = k // 4 + 1, k % 4
    if kind < 2:
        factor = 1.0 + (1 if kind == 0 else -1) * DENSITY_STEP * size
        return config.with_density_scaled(factor), f"density x {factor:.6g}"
    frames = (1 if kind == 2 else -1) * size
    settle = config.settle_s + frames / fps
    if settle < 0:
        raise ValueError(f"member {k} would settle {settle:.3f} s: use fewer members or a longer settle")
    return replace(config, settle_s=settle), f"settle {frames:+d} frame{'s' if abs(frames) > 1 else ''}"


@dataclass
class TruthEnsemble:
    """The K simulated truths of one sequence (members that exploded left out)."""

    name: str
    members: np.ndarray  # (K, T, V, 3) float32, world space
    perturbations: list[str]
    failed: dict[str, str]  # perturbation -> why its simulation was rejected


def record_settings(config: SimSettings, record: SequenceRecord) -> SimSettings:
    """The dataset's simulator ``config`` in the sequence's own cloth, where the build gave it one
    (its info's ``material``: sim/material_plan.py)."""
    cloth = record.info.get("material")
    return config if cloth is None else replace(config, material=material_from(cloth, record.name))


def _member_key(
    garment: GarmentMesh,
    record: SequenceRecord,
    config: SimSettings,
    body: BodyModel | None = None,
    visible: SkinnedBody | None = None,
) -> str:
    h = hashlib.sha256()
    h.update(
        json.dumps(
            {"version": ENSEMBLE_VERSION, "template": template_hash(garment), "config": config.to_dict()},
            sort_keys=True,
        ).encode()
    )
    if (
        body is not None
    ):  # on another body: its bones and capsules too (the mannequin's keys stay as they were)
        h.update(np.ascontiguousarray(body.skeleton.offsets, np.float64).tobytes())
        h.update(json.dumps([[c.name, c.joint, c.a, c.b, c.radius] for c in body.capsules]).encode())
    if visible is not None:  # collided with the body's own mesh (capsule-collided members are not these)
        for array in (visible.vertices, visible.faces, visible.weights):
            h.update(np.ascontiguousarray(array).tobytes())
    for array in (record.motion.local_rotations, record.motion.root_translation):
        h.update(np.ascontiguousarray(array).tobytes())
    h.update(repr(record.motion.fps).encode())
    return h.hexdigest()[:20]


def _simulate_member(
    garment: GarmentMesh,
    record: SequenceRecord,
    config: dict,
    path: str,
    on: tuple[BodyModel, SkinnedBody | None] = (DEFAULT_BODY, None),
) -> str | None:
    """Simulate one member into ``path`` (atomically) as the dataset simulated its sequence: on the
    body's capsules, or against its own mesh where it has one (``on``: the body and that mesh, as
    :class:`~hrr_garment.sim.parts.SequenceJob` collides); returns why it failed, or None."""
    body, visible = on
    collider = None if visible is None else skinned_pieces(body, visible)
    try:
        result = simulate_garment(
            garment, record.motion, SimSettings.from_dict(config), body=body, collider=collider
        )
    except SimulationExploded as exc:
        atomic_write_text(Path(path).with_suffix(".failed.json"), json.dumps({"reason": str(exc)}))
        return str(exc)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, result.vertices.astype(np.float32))
    return None


def _members_simulated(tasks: dict, workers: int) -> Iterator[tuple[tuple[str, int], str | None]]:
    """Each of ``tasks`` (member -> :func:`_simulate_member`'s arguments) simulated, as it finishes:
    (member, why it failed or None). In ``workers`` spawned processes that die with this one and
    are stopped at once by Ctrl-C, SIGTERM or an error here (each finished member is cached, so a
    re-run goes on from them); in this process where one worker would do (a worker would start
    Python and load the simulator again)."""
    if workers <= 1:
        for member, arguments in tasks.items():
            yield member, _simulate_member(*arguments)
        return
    with spawned_pool(workers) as pool:
        futures = {pool.submit(_simulate_member, *arguments): member for member, arguments in tasks.items()}
        for fut in as_completed(futures):
            yield futures[fut], fut.result()


def _readable(path: Path) -> bool:
    try:
        np.load(path, mmap_mode="r", allow_pickle=False)
        return True
    except (OSError, ValueError):
        return False


def _cached(path: Path) -> tuple[np.ndarray | None, str | None]:
    failed = path.with_suffix(".failed.json")
    if failed.is_file():
        return None, json.loads(failed.read_text())["reason"]
    if path.is_file():
        try:
            return np.load(path, allow_pickle=False), None
        except (OSError, ValueError):
            return None, None  # unreadable: simulate again
    return None, None


def truth_ensembles(
    garment: GarmentMesh,
    records: list[SequenceRecord],
    config: SimSettings,
    members: int = 4,
    jobs: int | None = None,
    cache: str | Path | None = None,
    progress: bool = True,
    bodies: dict[str, DressedBody] | None = None,
) -> dict[str, TruthEnsemble]:
    """``members`` perturbed simulations of each record (cached; missing ones run in ``jobs``
    processes). A record on a body other than the mannequin is simulated on it, with the garment on
    it, from ``bodies`` (a dataset's :attr:`~hrr_garment.data.dataset.GarmentDataset.bodies`), against
    its own mesh where it has one, as the dataset was; a record in a cloth of its own, in it."""
    dressed = {
        r.name: (bodies[r.body_name].garment, bodies[r.body_name].body, bodies[r.body_name].visible)
        if r.body_name != MANNEQUIN
        else (garment, None, None)
        for r in records
    }
    if members < 2:
        raise ValueError(f"an ensemble needs at least 2 members, got {members}")
    cache = Path(cache) if cache is not None else workspace() / "cache" / "ensemble"
    cache.mkdir(parents=True, exist_ok=True)
    plan: dict[tuple[str, int], tuple[Path, SimSettings, str]] = {}
    for record in records:
        own = record_settings(config, record)
        for k in range(members):
            cfg, label = member_config(own, k, record.motion.fps)
            on, body, visible = dressed[record.name]
            key = _member_key(on, record, cfg, body, visible)
            plan[record.name, k] = (cache / f"{key}.npy", cfg, label)
    missing = [
        (name, k)
        for (name, k), (path, _, _) in plan.items()
        if not path.with_suffix(".failed.json").is_file() and not _readable(path)
    ]
    if missing:
        by_name = {r.name: r for r in records}
        frames = sum(by_name[name].motion.num_frames for name, _ in missing)
        print(
            f"simulating {len(missing)} ensemble member(s) of {len(records)} sequence(s) ({frames} frames; "
            f"cached in {cache})"
        )
        tasks = {
            (name, k): (
                dressed[name][0],
                by_name[name],
                plan[name, k][1].to_dict(),
                str(plan[name, k][0]),
                (dressed[name][1] or DEFAULT_BODY, dressed[name][2]),
            )
            for name, k in missing
        }
        workers = min(jobs or os.cpu_count() or 1, len(tasks))
        with (
            tqdm(total=frames, unit="frame", desc="ensemble truth", disable=not progress) as bar,
            closing(_members_simulated(tasks, workers)) as simulated,  # an error here stops the pool too
        ):
            for (name, k), reason in simulated:
                if reason is not None:
                    bar.write(f"ensemble member {k} of {name} rejected: {reason}")
                bar.update(by_name[name].motion.num_frames)
    out = {}
    for record in records:
        arrays, labels, failed = [], [], {}
        for k in range(members):
            path, _, label = plan[record.name, k]
            vertices, reason = _cached(path)
            if vertices is None:
                failed[label] = reason or "missing"
            else:
                arrays.append(vertices)
                labels.append(label)
        if len(arrays) >= 2:
            out[record.name] = TruthEnsemble(record.name, np.stack(arrays), labels, failed)
    return out
