"""Cloth simulation of one garment over one motion with newton's VBD solver (extra ``sim``).

The body is a set of kinematic capsules (one rigid body each) moved every substep by interpolating
the motion's per-frame capsule transforms; the garment's attached vertices have zero mass and are
written every substep from their skinned positions. Parameters and the reasons for them are in
docs/dataset.md (measured here): penetration is governed by the substep count, stretch by
convergence, so the defaults are 10 substeps x 3 iterations.

A frame that is not finite, moves faster than ``max_speed`` or stretches an edge beyond
``max_strain`` raises :class:`SimulationExploded`; ``simulate_garment`` retries with twice the
substeps (``retries`` times), and, for a motion whose own limbs pass through the body
(:mod:`hrr_garment.body.self_contact`), with the arms (upper arms, forearms, hands) not touching
the cloth: first during those episodes only, then over the whole clip. An arm sunk into the hips or
belly pinches the cloth between two overlapping capsules and tears it, while an arm passing through
the cloth is a small, visible flaw of the capture's own making; keeping the arms on the cloth
outside the episodes keeps it outside them there. (Forearms and hands alone saved a Bandai wave
but not CMU 131_01 / 131_03 at 4,266 vertices; with the upper arms all three hold.) The newton scene
itself (bodies, cloth, captured substeps) is :mod:`.scene`. When every attempt has failed, one last
one doubles the substeps again: motion too fast for the schedule (a spin at 4 turns a second) holds
there, and only the clips that need it pay for it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, frames_signed_distance
from ..body.mesh_collider import SkinnedPieces
from ..body.retarget import played_by
from ..body.self_contact import LOWER_ARM, self_intersecting_frames
from ..errors import HRRError
from ..garment.attachment import bind_attached, bind_attached_to_skin, riding_skin
from ..garment.mesh import GarmentMesh
from ..motion.motion import Motion
from .capsule_poses import arms_off_capsules, capsule_transforms
from .config import SimSettings  # defined in .config (the scene needs it too); importable from here as before
from .lead_in import start_transform, with_lead_in
from .scene import ClothScene

# after an episode the arms come back on once at most this fraction of the cloth is inside them:
# first 0.5 % (CMU 131_01 then 0.07 % outside flagged frames, where waiting for none left the
# arms off, through the cloth, for 31 more frames: 1.43 %), then, if that tears, none (131_03)
ARMS_BACK_INSIDE = (0.005, 0.0)


class SimulationExploded(HRRError):
    """The cloth blew up (non-finite, too fast, or over-stretched) at some frame."""


@dataclass
class SimResult:
    """Recorded frames (T, V, 3) float32 in world space, for the clip's frames only."""

    vertices: np.ndarray
    substeps: int
    attempts: int
    seconds: float  # wall time of the successful attempt, scene building included
    simulated_frames: int  # lead-in included
    step_seconds: float = 0.0  # time spent stepping the solver (steady-state cost)
    arms_off_frames: int = 0  # clip frames on which the arms did not touch the cloth (the last retries)


class ClipRun:
    """One sequence's frame-by-frame inputs to a scene and the checks on what comes back: the
    lead-in and clip as capsule poses and pinned positions, the arms-off schedule, the explosion
    checks and the recorded frames. One attempt (:func:`_attempt`) drives one of these through a
    :class:`~.scene.ClothScene`; a batch (:mod:`.batch`) drives many through one model, so both
    apply exactly the same rules.

    ``arms_off``: (T,) clip frames on which the arms do not touch the cloth (the lead-in follows the
    clip's first frame). The arms come back only once at most ``back_inside`` of the cloth is inside
    them: switched on around cloth that an arm passed through, the contact throws it out at once
    (CMU 131_03 tore the full dress nine frames after an episode ended). ``collider``: the body the
    viewer sees collides instead of the capsules, its pieces reshaped every frame (:attr:`pieces`)."""

    def __init__(
        self,
        garment: GarmentMesh,
        motion: Motion,
        body: BodyModel,
        config: SimSettings,
        arms_off: np.ndarray | None = None,
        back_inside: float = 0.0,
        collider: SkinnedPieces | None = None,
    ):
        if collider is not None:  # on the body the viewer sees, straps ride its skin whole
            garment = riding_skin(garment)
        self.garment, self.motion, self.body, self.config, self.back_inside = (
            garment,
            motion,
            body,
            config,
            back_inside,
        )
        extended, self.lead = with_lead_in(
            motion, config.settle_s, config.blend_s, pelvis_height=body.pelvis_height
        )
        self.num_frames = extended.num_frames  # simulated frames, lead-in included
        if arms_off is None:
            arms_off = np.zeros(motion.num_frames, bool)
        self.arms_off = np.concatenate([np.full(self.lead, arms_off[0]), arms_off])
        rot_y, shift = start_transform(motion)
        self.start = garment.vertices.astype(np.float64) @ rot_y.T + shift
        centre, quat, self.half_lengths = capsule_transforms(extended, body)
        self.poses = np.concatenate([centre, quat], -1)
        # (T, N, 3) every skinned piece's vertices in its capsule's frame, frame by frame
        self.piece_local = None if collider is None else collider.local_frames(extended, centre, quat)
        self.collider = collider
        # on the body the viewer sees, the pins ride its skin (the torso's capsules alone left a strap
        # inside the shoulder's skin, which follows the arm)
        binding = (
            bind_attached(garment, body)
            if collider is None
            else bind_attached_to_skin(garment, collider.skin, body)
        )
        self.pins = binding.pose(extended.global_rotations.astype(np.float64), extended.joint_positions)
        self.arms = arms_off_capsules(body)
        self.arm_a, self.arm_b = (ends[:, self.arms] for ends in body.pose_motion(extended))
        self.edges = garment.edges()
        self.rest_len = np.linalg.norm(
            garment.vertices[self.edges[:, 0]] - garment.vertices[self.edges[:, 1]], axis=1
        )
        self.dt = 1.0 / motion.fps
        self.recorded = np.empty((motion.num_frames, garment.num_vertices, 3), np.float32)

    def arms_touch(self, frame: int, current: Callable[[], np.ndarray], arm_contact: bool) -> bool:
        """Whether the arms touch the cloth on ``frame``: not on a scheduled frame, nor while they are
        off and more than ``back_inside`` of the cloth (``current()``, read only then) is inside them."""
        if (
            self.arms_off[frame]
            or not arm_contact
            and _inside_fraction(current(), self.arm_a[frame], self.arm_b[frame], self.body.radii[self.arms])
            > self.back_inside
        ):
            self.arms_off[frame] = True  # kept off until the cloth is clear of them
        return not self.arms_off[frame]

    def scene_pieces(self) -> list[tuple[int, np.ndarray, np.ndarray]] | None:
        """The skinned pieces as a scene builds them (capsule, vertices at the first frame, faces)."""
        if self.collider is None:
            return None
        rows = self.collider.offsets
        return [
            (p.capsule, self.piece_local[0, rows[i] : rows[i + 1]], p.faces)
            for i, p in enumerate(self.collider.pieces)
        ]

    def piece_frames(self, frame: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The skinned pieces' vertices from the previous frame to ``frame`` (a scene's step)."""
        if self.piece_local is None:
            return None
        return self.piece_local[max(frame - 1, 0)], self.piece_local[frame]

    def check(self, frame: int, verts: np.ndarray, speeds: np.ndarray) -> None:
        """Raise :class:`SimulationExploded` when ``frame``'s positions are not finite, a point moves
        faster than ``max_speed`` or an edge is stretched beyond ``max_strain``."""
        config, problem = self.config, None
        if not np.isfinite(verts).all():
            problem = "non-finite positions"
        else:
            speed = speeds.max()
            strain = (
                np.linalg.norm(verts[self.edges[:, 0]] - verts[self.edges[:, 1]], axis=1) / self.rest_len
            ).max()
            if speed > config.max_speed:
                problem = f"speed {speed:.1f} m/s > {config.max_speed}"
            elif strain > config.max_strain:
                problem = f"edge strain {strain:.2f} > {config.max_strain}"
        if problem:
            clip_frame = frame - self.lead
            where = f"clip frame {clip_frame}" if clip_frame >= 0 else f"lead-in frame {frame}"
            raise SimulationExploded(
                f"{self.garment.name} on {self.motion.source}: {problem} at {where} "
                f"({config.substeps} substeps{_arms_note(self.arms_off[self.lead :])})"
            )

    def keep(self, frame: int, verts: np.ndarray) -> None:
        """Record ``frame``'s positions when it is one of the clip's (not the lead-in's)."""
        if frame >= self.lead:
            self.recorded[frame - self.lead] = verts

    @property
    def arms_off_frames(self) -> int:
        """Clip frames on which the arms did not touch the cloth."""
        return int(self.arms_off[self.lead :].sum())


def _attempt(
    garment: GarmentMesh,
    motion: Motion,
    body: BodyModel,
    config: SimSettings,
    progress: Callable[[int], None] | None,
    arms_off: np.ndarray | None = None,
    back_inside: float = 0.0,
    collider: SkinnedPieces | None = None,
) -> tuple[np.ndarray, int, float, int]:
    """One simulation (see :class:`ClipRun` for ``arms_off``, ``back_inside`` and ``collider``);
    returns (the clip's frames, simulated frames, seconds stepping, clip frames with the arms off)."""
    run = ClipRun(garment, motion, body, config, arms_off, back_inside, collider)
    scene = ClothScene(
        run.garment, run.start, run.half_lengths, body=body, config=config, pieces=run.scene_pieces()
    )
    stepping = 0.0
    for f in range(run.num_frames):
        prev = max(f - 1, 0)
        t0 = time.perf_counter()
        scene.set_arm_contact(run.arms_touch(f, scene.current, scene.arm_contact))
        verts = scene.step_frame(
            run.poses[prev],
            run.poses[f],
            run.pins[prev],
            run.pins[f],
            run.dt,
            config.substeps,
            pieces=run.piece_frames(f),
        )
        stepping += time.perf_counter() - t0
        run.check(f, verts, scene.speeds())
        run.keep(f, verts)
        if progress is not None:
            progress(1)
    return run.recorded, run.num_frames, stepping, run.arms_off_frames


def _inside_fraction(vertices: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray) -> float:
    """The fraction of vertices inside the capsules a-b (C, 3)."""
    return float((frames_signed_distance(vertices[None], a[None], b[None], radii=radii)[0] < 0).mean())


def _arms_note(arms_off: np.ndarray) -> str:
    if arms_off.all():
        return ", arms off the cloth"
    return f", arms off the cloth on {int(arms_off.sum())} frames" if arms_off.any() else ""


def simulate_garment(
    garment: GarmentMesh,
    motion: Motion,
    config: SimSettings = SimSettings(),
    body: BodyModel = DEFAULT_BODY,
    progress: Callable[[int], None] | None = None,
    collider: SkinnedPieces | None = None,
) -> SimResult:
    """Simulate ``garment`` on ``motion`` (30 fps canonical); on explosion retries with more substeps,
    then (for a motion with self-intersecting limbs) with the arms off the cloth during those
    episodes, then over the whole clip.

    ``collider``: the body the viewer sees, its skinned mesh in pieces
    (:func:`hrr_garment.body.mesh_collider.skinned_pieces`), collides with the cloth instead of the
    capsules; the capsules still decide when the arms are off the cloth.

    On a ``body`` other than the mannequin the motion plays on that body's skeleton: a clip on the
    canonical skeleton is played by the body (:func:`~hrr_garment.body.retarget.motion_on_body`);
    a clip on some other skeleton is refused.

    Raises :class:`SimulationExploded` (with every attempt's reason) when all attempts fail.
    """
    motion = played_by(motion, body)
    # (substeps, clip frames with the arms off the cloth, fraction of the cloth inside the arms they
    # come back at)
    attempts: list[tuple[int, np.ndarray | None, float]] = [
        (config.substeps * 2**k, None, 0.0) for k in range(config.retries + 1)
    ]
    reasons = []
    for number, (substeps, arms_off, back_inside) in enumerate(attempts, 1):
        cfg = replace(config, substeps=substeps)
        t0 = time.perf_counter()
        try:
            vertices, frames, stepping, off = _attempt(
                garment,
                motion,
                body,
                cfg,
                progress,
                arms_off,
                back_inside,
                collider,
            )
        except SimulationExploded as exc:
            reasons.append(str(exc))
            if number == config.retries + 1:  # every substep count failed: the arms, if they are the cause
                episodes = self_intersecting_frames(motion, body, parts=LOWER_ARM)
                if episodes.any() and not episodes.all():
                    attempts += [(config.substeps, episodes, inside) for inside in ARMS_BACK_INSIDE]
                if episodes.any():
                    attempts.append((config.substeps, np.ones_like(episodes), 0.0))
            if number == len(attempts) and substeps < config.substeps * 2 ** (config.retries + 1):
                # everything failed: a motion too fast for these substeps (a pirouette at 4 turns a
                # second tore the dress at 15 and 30, and held at 60) gets one more doubling, the
                # arms as the last attempt had them
                attempts.append((config.substeps * 2 ** (config.retries + 1), arms_off, back_inside))
            continue
        return SimResult(vertices, cfg.substeps, number, time.perf_counter() - t0, frames, stepping, off)
    raise SimulationExploded("; ".join(reasons))
