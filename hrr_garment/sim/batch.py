"""Many sequences simulated together: independent cloth instances in one newton model, each in its
own world with its own capsule body, so one solver step advances all of them (extra ``sim``).

newton's VBD solver is built for GPUs, where one garment of a few thousand vertices leaves most of
the device idle; a batch fills it. Isolation comes from newton's worlds: each instance's bodies,
capsules and cloth are added with :meth:`ModelBuilder.add_world`, and newton pairs a particle
only with shapes of its own world or global ones (``_world_compatible_pairs`` builds the
candidate pairs, and ``create_soft_contacts`` skips a particle and a shape of two different
worlds), so a cloth never touches another instance's body. The ground plane is the one global
shape. Each instance keeps the colouring it has alone (its own colour groups, merged colour by
colour), so VBD updates its vertices in the same order as :class:`~.scene.ClothScene` does.

:func:`simulate_batch` drives every instance with the same per-frame rules as
:func:`~.simulator.simulate_garment`'s attempts (:class:`~.simulator.ClipRun`: lead-in, pinned
vertices, arms-off schedule, explosion checks). A shorter sequence holds its last pose once its
frames are done and is no longer checked or recorded. An instance that explodes is frozen (its
particles made inactive) and dropped from the batch; it is then simulated alone by
``simulate_garment`` from its first attempt, with all its retries, so what is kept or rejected
follows the per-sequence path's policy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..body.capsules import BodyModel
from ..body.mesh_collider import SkinnedPieces
from ..body.retarget import played_by
from ..garment.mesh import GarmentMesh
from ..motion.motion import Motion
from .capsule_poses import arms_off_capsules
from .config import SimSettings
from .scene import SteppedScene, add_ground, import_newton, instance_builder, resolve_device
from .simulator import ClipRun, SimResult, SimulationExploded, simulate_garment


@dataclass(frozen=True)
class BatchItem:
    """One sequence of a batch: the garment on its body, the motion (on the body's skeleton, or a
    canonical clip that the body plays), the body's capsules and, where the body has a mesh, the
    collider that is that mesh (:func:`~hrr_garment.sim.simulator.simulate_garment`'s)."""

    garment: GarmentMesh
    motion: Motion
    body: BodyModel
    collider: SkinnedPieces | None = None


def _merged_groups(groups: list[list[np.ndarray]], offsets: list[int]) -> list[np.ndarray]:
    """Colour groups of several instances merged colour by colour, each shifted by its offset."""
    colours = max((len(g) for g in groups), default=0)
    return [
        np.concatenate([np.asarray(g[c], int) + offset for g, offset in zip(groups, offsets) if c < len(g)])
        for c in range(colours)
    ]


class BatchScene(SteppedScene):
    """One newton model holding ``runs``' instances, each in its own world (see the module
    docstring); ``ranges[i]`` are instance ``i``'s particles in the concatenated positions."""

    def __init__(self, runs: list[ClipRun], config: SimSettings):
        wp, newton = import_newton()
        self.wp, self.newton, self.config = wp, newton, config
        self.device = resolve_device(wp, config.device)
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -config.gravity, 0.0))
        particle_groups, body_groups, arm_shapes, attached = [], [], [], []
        particle_starts, body_starts, self.ranges, piece_shapes = [], [], [], []
        for run in runs:
            pieces = run.scene_pieces()
            instance, shapes = instance_builder(
                run.garment, run.start, run.half_lengths, body=run.body, config=config, pieces=pieces
            )
            first_particle, first_shape = builder.particle_count, builder.shape_count
            particle_starts.append(first_particle)
            body_starts.append(builder.body_count)
            builder.add_world(instance)
            particle_groups.append(instance.particle_color_groups)
            body_groups.append(instance.body_color_groups)
            arm_shapes.append([first_shape + s for c in arms_off_capsules(run.body) for s in shapes[c]])
            piece_shapes += [first_shape + shapes[c][0] for c, _, _ in pieces or ()]
            attached.append(first_particle + np.asarray(run.garment.attached, np.int64))
            self.ranges.append(slice(first_particle, builder.particle_count))
        add_ground(builder, config)  # global: every world's cloth meets it
        builder.set_coloring(_merged_groups(particle_groups, particle_starts))
        builder.body_color_groups = _merged_groups(body_groups, body_starts)
        self._finish(builder, config, arm_shapes, np.concatenate(attached), piece_shapes)

    def instance_positions(self, instance: int) -> np.ndarray:
        """Instance ``instance``'s current positions (V, 3)."""
        return self.current()[self.ranges[instance]]

    def freeze(self, instance: int) -> None:
        """Take an instance out of the solve (its particles inactive): one that exploded."""
        flags = self.model.particle_flags.numpy()
        flags[self.ranges[instance]] &= ~int(self.newton.ParticleFlags.ACTIVE)
        self.model.particle_flags.assign(flags)


def _frame_inputs(runs: list[ClipRun], frame: int) -> tuple[np.ndarray, ...]:
    """Every instance's capsule poses and pinned positions from the previous frame to ``frame``,
    concatenated; a finished instance holds its last frame."""
    last = [min(frame, r.num_frames - 1) for r in runs]
    prev = [max(min(frame - 1, r.num_frames - 1), 0) for r in runs]
    return (
        np.concatenate([r.poses[p] for r, p in zip(runs, prev)]),
        np.concatenate([r.poses[f] for r, f in zip(runs, last)]),
        np.concatenate([r.pins[p] for r, p in zip(runs, prev)]),
        np.concatenate([r.pins[f] for r, f in zip(runs, last)]),
    )


def _piece_inputs(runs: list[ClipRun], frame: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Every instance's skinned pieces from the previous frame to ``frame``, concatenated in the
    scene's order (a finished instance holds its last frame); None when no instance has any."""
    mine = [r for r in runs if r.piece_local is not None]
    if not mine:
        return None
    last = [min(frame, r.num_frames - 1) for r in mine]
    prev = [max(min(frame - 1, r.num_frames - 1), 0) for r in mine]
    return (
        np.concatenate([r.piece_local[p] for r, p in zip(mine, prev)]),
        np.concatenate([r.piece_local[f] for r, f in zip(mine, last)]),
    )


def step_batch(
    scene: BatchScene, runs: list[ClipRun], progress: Callable[[int], None] | None = None
) -> tuple[dict[int, str], float]:
    """Advance every instance through its frames (the longest sets the count); returns (why each
    exploded instance was dropped, by instance, and the seconds spent stepping)."""
    config = scene.config
    dropped: dict[int, str] = {}
    stepping = 0.0
    for f in range(max(r.num_frames for r in runs)):
        playing = [i for i, r in enumerate(runs) if i not in dropped and f < r.num_frames]
        t0 = time.perf_counter()
        wanted = list(scene.arm_contacts)
        for i in playing:
            wanted[i] = runs[i].arms_touch(f, lambda i=i: scene.instance_positions(i), scene.arm_contacts[i])
        scene.set_arm_contacts(wanted)
        verts = scene.step_frame(
            *_frame_inputs(runs, f), dt=runs[0].dt, substeps=config.substeps, pieces=_piece_inputs(runs, f)
        )
        stepping += time.perf_counter() - t0
        speeds = scene.speeds()
        for i in playing:
            mine = scene.ranges[i]
            try:
                runs[i].check(f, verts[mine], speeds[mine])
            except SimulationExploded as exc:
                dropped[i] = str(exc)
                scene.freeze(i)
                continue
            runs[i].keep(f, verts[mine])
        if progress is not None:
            progress(len(playing))
    return dropped, stepping


def simulate_batch(
    items: list[BatchItem], config: SimSettings = SimSettings(), progress: Callable[[int], None] | None = None
) -> list[SimResult | SimulationExploded]:
    """Simulate ``items`` together (one model, one solver, ``config``'s substeps and iterations for
    all); each gets what :func:`~.simulator.simulate_garment` gives it: its result, or the
    :class:`SimulationExploded` that rejects it. An instance that explodes in the batch is
    simulated alone by ``simulate_garment`` (every attempt and retry). A batched result's
    ``seconds`` and ``step_seconds`` are the batch's shared out by simulated frames."""
    if len({item.motion.fps for item in items}) > 1:
        raise ValueError("a batch steps every instance with one frame time: give it clips of one frame rate")
    t0 = time.perf_counter()
    motions = [played_by(item.motion, item.body) for item in items]
    runs = [
        ClipRun(item.garment, motion, body=item.body, config=config, collider=item.collider)
        for item, motion in zip(items, motions)
    ]
    dropped, stepping = step_batch(BatchScene(runs, config), runs, progress)
    wall = time.perf_counter() - t0
    total = sum(r.num_frames for r in runs)
    results: list[SimResult | SimulationExploded] = []
    for i, (item, run) in enumerate(zip(items, runs)):
        if i not in dropped:
            share = run.num_frames / total
            results.append(
                SimResult(
                    run.recorded,
                    substeps=config.substeps,
                    attempts=1,
                    seconds=wall * share,
                    simulated_frames=run.num_frames,
                    step_seconds=stepping * share,
                    arms_off_frames=run.arms_off_frames,
                )
            )
            continue
        try:
            results.append(
                simulate_garment(
                    item.garment,
                    motions[i],
                    config,
                    body=item.body,
                    progress=progress,
                    collider=item.collider,
                )
            )
        except SimulationExploded as exc:
            results.append(exc)
    return results
