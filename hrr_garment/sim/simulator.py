"""Cloth simulation of one garment over one motion with newton's VBD solver (extra ``sim``).

The body is a set of kinematic capsules (one rigid body each) moved every substep by interpolating
the motion's per-frame capsule transforms; the garment's attached vertices have zero mass and are
written every substep from their skinned positions. Parameters and the reasons for them are in
DESIGN.md section 8 (measured here): penetration is governed by the substep count, stretch by
convergence, so the defaults are 10 substeps x 3 iterations.

A frame that is not finite, moves faster than ``max_speed`` or stretches an edge beyond
``max_strain`` raises :class:`SimulationExploded`; ``simulate_garment`` retries with twice the
substeps, and, for a motion whose own limbs pass through the body
(:mod:`hrr_garment.body.self_contact`), with the arms (upper arms, forearms, hands) not touching
the cloth: first during those episodes only, then over the whole clip. An arm sunk into the hips or
belly pinches the cloth between two overlapping capsules and tears it, while an arm passing through
the cloth is a small, visible flaw of the capture's own making; keeping the arms on the cloth
outside the episodes keeps it outside them there. (Forearms and hands alone saved a Bandai wave
but not CMU 131_01 / 131_03 at 4,266 vertices; with the upper arms all three hold.)
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace
from typing import Callable

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, frames_signed_distance
from ..body.self_contact import ARM_PARTS, self_intersecting_frames
from ..errors import HRRError
from ..garment.attachment import bind_attached
from ..garment.mesh import GarmentMesh
from ..motion.motion import Motion
from ..motion.rotations import matrix_to_quat, rotation_between
from ..settings import from_settings
from .lead_in import start_transform, with_lead_in

NEWTON_VERSION = "1.8.0"
ARM_CAPSULES = ("upper_arm", "forearm", "hand")  # taken off the cloth in the last retries
# after an episode the arms come back on once at most this fraction of the cloth is inside them:
# first 0.5 % (CMU 131_01 then 0.07 % outside flagged frames, where waiting for none left the
# arms off, through the cloth, for 31 more frames: 1.43 %), then, if that tears, none (131_03)
ARMS_BACK_INSIDE = (0.005, 0.0)


def arm_capsules(body: BodyModel) -> list[int]:
    """Indices into ``body.capsules`` of the capsules the arms-off retries take off the cloth."""
    return [c for c, capsule in enumerate(body.capsules) if capsule.name.endswith(tuple(f"_{p}" for p in ARM_CAPSULES))]


class SimulationExploded(HRRError):
    """The cloth blew up (non-finite, too fast, or over-stretched) at some frame."""


@dataclass(frozen=True)
class SimConfig:
    """Solver and material values; configs/sim.yaml holds the project defaults."""

    substeps: int = 10
    iterations: int = 3
    tri_ke: float = 1.0e4  # membrane stretch stiffness
    tri_ka: float = 1.0e4  # membrane area stiffness
    tri_kd: float = 1.0e-4  # membrane damping
    edge_ke: float = 1.0e-3  # bending stiffness
    edge_kd: float = 1.0e-4  # bending damping
    density: float = 0.15  # kg per square metre
    particle_radius: float = 0.006
    contact_ke: float = 3.0e4  # 1e4 let running thighs push 1 % of a dress 2 cm in; 3e4: none
    contact_kd: float = 1.0e-2
    contact_mu: float = 0.3
    contact_gap: float = 0.01  # contact detection distance beyond the radius
    gravity: float = 9.81
    settle_s: float = 0.5
    blend_s: float = 0.8  # arms come down from the T-pose at under 3 m/s
    max_speed: float = 30.0  # m/s: a garment point moving faster has exploded
    max_strain: float = 2.5  # edge length / rest length beyond which the cloth has exploded
    retries: int = 1  # extra attempts, each with twice the substeps
    device: str = "auto"  # "auto" (a GPU when present), "cpu", "cuda:0"...

    @classmethod
    def from_dict(cls, values: dict) -> "SimConfig":
        return from_settings(cls, values, "simulator")

    def to_dict(self) -> dict:
        return asdict(self)


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


def _import_newton():
    try:
        import warp as wp

        wp.config.quiet = True  # no banner
        wp.config.log_level = wp.LOG_WARNING  # no per-module load timings
        import newton
    except ImportError:
        raise ImportError("the cloth simulator needs newton and warp: pip install 'hrr_garment[sim]'") from None
    return wp, newton


def capsule_transforms(motion: Motion, body: BodyModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame and capsule: centre (T, C, 3), quaternion (T, C, 4) as x, y, z, w rotating +Z onto
    the capsule axis, and the half length of the axis (C,)."""
    joint_idx = [motion.skeleton.names.index(c.joint) for c in body.capsules]
    a_loc = np.array([c.a for c in body.capsules])
    b_loc = np.array([c.b for c in body.capsules])
    axis = b_loc - a_loc
    half = 0.5 * np.linalg.norm(axis, axis=1)
    align = rotation_between(np.broadcast_to([0.0, 0.0, 1.0], axis.shape), axis)  # (C, 3, 3) in joint frame
    rot = motion.global_rotations[:, joint_idx].astype(np.float64) @ align[None]
    centre = motion.joint_positions[:, joint_idx] + np.einsum("tcij,cj->tci", motion.global_rotations[:, joint_idx], 0.5 * (a_loc + b_loc))
    q = matrix_to_quat(rot)  # w, x, y, z
    return centre, np.concatenate([q[..., 1:], q[..., :1]], -1), half


def _nlerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    q1 = np.where(((q0 * q1).sum(-1, keepdims=True) < 0), -q1, q1)
    q = (1 - t) * q0 + t * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def resolve_device(wp, device: str) -> str:
    """The warp device for ``device`` (``auto``: the first GPU, else the CPU)."""
    if device == "auto":
        return "cuda:0" if wp.get_cuda_device_count() > 0 else "cpu"
    return device


class _Scene:
    """A newton model of one garment and the capsule body, stepped frame by frame."""

    def __init__(self, garment: GarmentMesh, start_vertices: np.ndarray, half_lengths: np.ndarray,
                 body: BodyModel, config: SimConfig):
        wp, newton = _import_newton()
        self.wp, self.config = wp, config
        self.device = resolve_device(wp, config.device)
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -config.gravity, 0.0))
        shape_cfg = newton.ModelBuilder.ShapeConfig(ke=config.contact_ke, kd=config.contact_kd, mu=config.contact_mu,
                                                    has_shape_collision=False)
        shapes = []
        for c, capsule in enumerate(body.capsules):
            b = builder.add_body(mass=0.0, is_kinematic=True, label=capsule.name)
            shapes.append(builder.add_shape_capsule(b, radius=capsule.radius, half_height=float(half_lengths[c]), cfg=shape_cfg))
        self.arm_shapes = [shapes[c] for c in arm_capsules(body)]
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(ke=config.contact_ke, kd=config.contact_kd,
                                                                    mu=config.contact_mu))
        builder.add_cloth_mesh(
            pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
            vertices=[wp.vec3(*v) for v in start_vertices.astype(float)], indices=garment.faces.ravel().tolist(),
            density=config.density, tri_ke=config.tri_ke, tri_ka=config.tri_ka, tri_kd=config.tri_kd,
            edge_ke=config.edge_ke, edge_kd=config.edge_kd, particle_radius=config.particle_radius,
        )
        for i in garment.attached:
            builder.particle_mass[int(i)] = 0.0  # zero mass: pinned, positions written each substep
        builder.color(include_bending=True)
        self.model = builder.finalize(device=self.device)
        self.model.soft_contact_ke = config.contact_ke
        self.model.soft_contact_kd = config.contact_kd
        self.model.soft_contact_mu = config.contact_mu
        self.pipeline = newton.CollisionPipeline(self.model, soft_contact_gap=config.contact_gap)
        self.contacts = self.pipeline.contacts()
        self.solver = newton.solvers.SolverVBD(self.model, iterations=config.iterations,
                                               integrate_with_external_rigid_solver=True)
        self.states = (self.model.state(), self.model.state())
        self.control = self.model.control()
        self.attached = garment.attached
        self.parity = 0  # states[parity] holds the current positions
        self.graphs: list = [None, None]
        self.arm_contact = True
        self.collide_particles = int(newton.ShapeFlags.COLLIDE_PARTICLES)

    def set_arm_contact(self, on: bool) -> None:
        """Let the arm capsules touch the cloth or not. The contact kernels read the shape flags on
        every launch (captured graphs included) and VBD's candidate tables stay valid."""
        if on == self.arm_contact:
            return
        flags = self.model.shape_flags.numpy()
        flags[self.arm_shapes] = flags[self.arm_shapes] | self.collide_particles if on else \
            flags[self.arm_shapes] & ~self.collide_particles
        self.model.shape_flags.assign(flags)
        self.arm_contact = on

    def _substep(self, parity: int, dt: float) -> None:
        state_in, state_out = self.states[parity], self.states[1 - parity]
        self.pipeline.collide(state_in, self.contacts)
        self.solver.step(state_in, state_out, self.control, self.contacts, dt)

    def _run_substep(self, dt: float) -> None:
        """One substep, replayed from a captured graph: Python launch overhead dominates otherwise."""
        wp, p = self.wp, self.parity
        if getattr(self, "_dt", dt) != dt:
            raise ValueError("a scene replays graphs captured for one substep length; build a new scene")
        self._dt = dt
        if self.graphs[p] is None:
            self._substep(p, dt)  # first run loads modules and lets the solver initialise
            self.graphs[p] = "ready"
        elif self.graphs[p] == "ready":
            with wp.ScopedCapture(device=self.device) as capture:
                self._substep(p, dt)
            self.graphs[p] = capture.graph
            wp.capture_launch(capture.graph)
        else:
            wp.capture_launch(self.graphs[p])
        self.parity = 1 - p

    def step_frame(self, body_from: np.ndarray, body_to: np.ndarray, pin_from: np.ndarray, pin_to: np.ndarray,
                   dt: float, substeps: int) -> np.ndarray:
        """Advance one frame; body_* (C, 7) [p, q(xyzw)], pin_* (A, 3). Returns positions (V, 3)."""
        for k in range(substeps):
            t0, t1 = k / substeps, (k + 1) / substeps
            state_in, state_out = self.states[self.parity], self.states[1 - self.parity]
            # The solver derives body contact velocities from the old (input) and new (output) poses.
            for state, t in ((state_in, t0), (state_out, t1)):
                pose = np.concatenate([(1 - t) * body_from[:, :3] + t * body_to[:, :3],
                                       _nlerp(body_from[:, 3:], body_to[:, 3:], t)], 1)
                state.body_q.assign(pose.astype(np.float32))
            q = state_in.particle_q.numpy()
            q[self.attached] = (1 - t1) * pin_from + t1 * pin_to
            state_in.particle_q.assign(q)
            self._run_substep(dt / substeps)
        return self.states[self.parity].particle_q.numpy().copy()

    def current(self) -> np.ndarray:
        return self.states[self.parity].particle_q.numpy()

    def speeds(self) -> np.ndarray:
        return np.linalg.norm(self.states[self.parity].particle_qd.numpy(), axis=1)


def _attempt(garment: GarmentMesh, motion: Motion, body: BodyModel, config: SimConfig,
             progress: Callable[[int], None] | None, arms_off: np.ndarray | None = None,
             back_inside: float = 0.0) -> tuple[np.ndarray, int, float, int]:
    """One simulation; ``arms_off``: (T,) clip frames on which the arms do not touch the cloth (the
    lead-in follows the clip's first frame). The arms come back only once at most ``back_inside``
    of the cloth is inside them: switched on around cloth that an arm passed
    through, the contact throws it out at once (CMU 131_03 tore the full dress nine frames after an
    episode ended)."""
    extended, lead = with_lead_in(motion, config.settle_s, config.blend_s)
    if arms_off is None:
        arms_off = np.zeros(motion.num_frames, bool)
    arms_off = np.concatenate([np.full(lead, arms_off[0]), arms_off])
    rot_y, shift = start_transform(motion)
    start = garment.vertices.astype(np.float64) @ rot_y.T + shift
    centre, quat, half = capsule_transforms(extended, body)
    poses = np.concatenate([centre, quat], -1)
    binding = bind_attached(garment, body)
    pins = binding.pose(extended.global_rotations.astype(np.float64), extended.joint_positions)
    scene = _Scene(garment, start, half, body, config)
    arms = arm_capsules(body)
    arm_a, arm_b = (ends[:, arms] for ends in body.pose_motion(extended))
    edges = garment.edges()
    rest_len = np.linalg.norm(garment.vertices[edges[:, 0]] - garment.vertices[edges[:, 1]], axis=1)
    dt = 1.0 / motion.fps
    recorded = np.empty((motion.num_frames, garment.num_vertices, 3), np.float32)
    stepping = 0.0
    for f in range(extended.num_frames):
        prev = max(f - 1, 0)
        t0 = time.perf_counter()
        if arms_off[f] or not scene.arm_contact and \
                _inside_fraction(scene.current(), arm_a[f], arm_b[f], body.radii[arms]) > back_inside:
            arms_off[f] = True  # kept off until the cloth is clear of them
        scene.set_arm_contact(not arms_off[f])
        verts = scene.step_frame(poses[prev], poses[f], pins[prev], pins[f], dt, config.substeps)
        stepping += time.perf_counter() - t0
        clip_frame = f - lead
        problem = None
        if not np.isfinite(verts).all():
            problem = "non-finite positions"
        else:
            speed = scene.speeds().max()
            strain = (np.linalg.norm(verts[edges[:, 0]] - verts[edges[:, 1]], axis=1) / rest_len).max()
            if speed > config.max_speed:
                problem = f"speed {speed:.1f} m/s > {config.max_speed}"
            elif strain > config.max_strain:
                problem = f"edge strain {strain:.2f} > {config.max_strain}"
        if problem:
            where = f"clip frame {clip_frame}" if clip_frame >= 0 else f"lead-in frame {f}"
            raise SimulationExploded(f"{garment.name} on {motion.source}: {problem} at {where} "
                                     f"({config.substeps} substeps{_arms_note(arms_off[lead:])})")
        if clip_frame >= 0:
            recorded[clip_frame] = verts
        if progress is not None:
            progress(1)
    return recorded, extended.num_frames, stepping, int(arms_off[lead:].sum())


def _inside_fraction(vertices: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray) -> float:
    """The fraction of vertices inside the capsules a-b (C, 3)."""
    return float((frames_signed_distance(vertices[None], a[None], b[None], radii)[0] < 0).mean())


def _arms_note(arms_off: np.ndarray) -> str:
    if arms_off.all():
        return ", arms off the cloth"
    return f", arms off the cloth on {int(arms_off.sum())} frames" if arms_off.any() else ""


def simulate_garment(garment: GarmentMesh, motion: Motion, config: SimConfig = SimConfig(),
                     body: BodyModel = DEFAULT_BODY, progress: Callable[[int], None] | None = None) -> SimResult:
    """Simulate ``garment`` on ``motion`` (30 fps canonical); on explosion retries with more substeps,
    then (for a motion with self-intersecting limbs) with the arms off the cloth during those
    episodes, then over the whole clip.

    Raises :class:`SimulationExploded` (with every attempt's reason) when all attempts fail.
    """
    # (substeps, clip frames with the arms off the cloth, fraction of the cloth inside the arms they come back at)
    attempts: list[tuple[int, np.ndarray | None, float]] = [(config.substeps * 2 ** k, None, 0.0)
                                                          for k in range(config.retries + 1)]
    reasons = []
    for number, (substeps, arms_off, back_inside) in enumerate(attempts, 1):
        cfg = replace(config, substeps=substeps)
        t0 = time.perf_counter()
        try:
            vertices, frames, stepping, off = _attempt(garment, motion, body, cfg, progress, arms_off, back_inside)
        except SimulationExploded as exc:
            reasons.append(str(exc))
            if number == config.retries + 1:  # every substep count failed: the arms, if they are the cause
                episodes = self_intersecting_frames(motion, body, parts=ARM_PARTS)
                if episodes.any() and not episodes.all():
                    attempts += [(config.substeps, episodes, inside) for inside in ARMS_BACK_INSIDE]
                if episodes.any():
                    attempts.append((config.substeps, np.ones_like(episodes), 0.0))
            continue
        return SimResult(vertices, cfg.substeps, number, time.perf_counter() - t0, frames, stepping, off)
    raise SimulationExploded("; ".join(reasons))
