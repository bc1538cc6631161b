"""The newton scene the simulator steps: the capsule body as kinematic rigid bodies, the garment as
VBD cloth with its attached vertices pinned (zero mass, written every substep), advanced one frame
at a time from captured CUDA/CPU graphs. :mod:`.simulator` decides what to simulate and how to
retry; this module only talks to newton and warp (extra ``sim``).
"""

from __future__ import annotations

import numpy as np

from ..body.capsules import BodyModel
from ..garment.mesh import GarmentMesh
from .air_drag import AirDrag
from .capsule_poses import arms_off_capsules, nlerp
from .cloth_parameters import cloth_parameters, hinge_stiffness
from .cloth_viscosity import ClothViscosity
from .config import SimSettings

# how far a skinned piece's skin may stray from its bone's rigid motion (its box, set at rest, is
# widened by this): skinning moves the skin at a bent joint by a few centimetres
PIECE_BOUNDS_PAD_M = 0.1


def import_newton():
    """warp and newton, quiet; a clear error when the ``sim`` extra is missing."""
    try:
        import warp as wp

        wp.config.quiet = True  # no banner
        wp.config.log_level = wp.LOG_WARNING  # no per-module load timings
        import newton
    except ImportError:
        raise ImportError(
            "the cloth simulator needs newton and warp: pip install 'hrr_garment[sim]'"
        ) from None
    return wp, newton


def resolve_device(wp, device: str) -> str:
    """The warp device for ``device`` (``auto``: the first GPU, else the CPU)."""
    if device == "auto":
        return "cuda:0" if wp.get_cuda_device_count() > 0 else "cpu"
    return device


def instance_builder(
    garment: GarmentMesh,
    start_vertices: np.ndarray,
    half_lengths: np.ndarray,
    body: BodyModel,
    config: SimSettings,
    pieces: list | None = None,
):
    """A newton builder of one garment (attached vertices at zero mass) and ``body``'s capsules as
    kinematic bodies, coloured for VBD, without the ground: a :class:`ClothScene` adds the ground
    to it, a batch (:mod:`.batch`) adds it as one world of many. ``pieces``: the body the viewer
    sees collides instead of its capsules, (capsule index, vertices in that capsule's frame, faces)
    per piece riding with the capsule's body (:mod:`hrr_garment.body.mesh_collider`), the vertices
    rewritten every frame (:meth:`SteppedScene.step_frame`). Returns (builder, each capsule's shape
    indices in it): a piece is the only shape of its capsule's body."""
    wp, newton = import_newton()
    builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -config.gravity, 0.0))
    shape_cfg = newton.ModelBuilder.ShapeConfig(
        ke=config.contact_ke, kd=config.contact_kd, mu=config.contact_mu, has_shape_collision=False
    )
    bodies = [builder.add_body(mass=0.0, is_kinematic=True, label=capsule.name) for capsule in body.capsules]
    shapes: list[list[int]] = [[] for _ in body.capsules]
    if pieces is None:
        for c, capsule in enumerate(body.capsules):
            shapes[c].append(
                builder.add_shape_capsule(
                    bodies[c], radius=capsule.radius, half_height=float(half_lengths[c]), cfg=shape_cfg
                )
            )
    else:
        for c, vertices, faces in pieces:
            mesh = newton.Mesh(np.asarray(vertices, np.float32), np.asarray(faces, np.int32).ravel())
            shapes[c].append(builder.add_shape_mesh(bodies[c], mesh=mesh, cfg=shape_cfg))
    cloth = cloth_parameters(config)
    first_edge = len(builder.edge_indices)
    builder.add_cloth_mesh(
        pos=wp.vec3(0.0, 0.0, 0.0),
        rot=wp.quat_identity(),
        scale=1.0,
        vel=wp.vec3(0.0, 0.0, 0.0),
        vertices=[wp.vec3(*v) for v in start_vertices.astype(float)],
        indices=garment.faces.ravel().tolist(),
        density=cloth.density,
        tri_ke=cloth.tri_ke,
        tri_ka=cloth.tri_ka,
        tri_kd=cloth.tri_kd,
        edge_ke=cloth.edge_ke,
        edge_kd=cloth.edge_kd,
        particle_radius=config.particle_radius,
    )
    if cloth.bend is not None:  # a material: each hinge's stiffness from its own rest geometry
        builder.edge_bending_properties[first_edge:] = hinge_stiffness(
            cloth, np.asarray(builder.particle_q, np.float64), np.asarray(builder.edge_indices[first_edge:])
        )
    for i in garment.attached:
        builder.particle_mass[int(i)] = 0.0  # zero mass: pinned, positions written each substep
    builder.color(include_bending=True)
    return builder, shapes


def add_ground(builder, config: SimSettings) -> None:
    """The ground plane (a global shape: in a batch every world's cloth meets it)."""
    _, newton = import_newton()
    builder.add_ground_plane(
        cfg=newton.ModelBuilder.ShapeConfig(ke=config.contact_ke, kd=config.contact_kd, mu=config.contact_mu)
    )


class SteppedScene:
    """A finalized newton model of one or more cloth instances, each with its own capsule body,
    stepped frame by frame from captured graphs. :class:`ClothScene` holds one instance; a batch
    (:class:`~hrr_garment.sim.batch.BatchScene`) holds many in separate worlds. The positions and
    poses it takes and returns are the instances' concatenated: ``attached`` indexes the whole
    model's particles, ``arm_shapes[i]`` are instance ``i``'s arm capsules."""

    def _finish(
        self,
        builder,
        config: SimSettings,
        arm_shapes: list[list[int]],
        attached: np.ndarray,
        piece_shapes: list[int] = (),
    ) -> None:
        """Finalize ``builder`` into the model, collision pipeline, solver and two states;
        ``piece_shapes``: the skinned pieces' shapes, in the order :meth:`set_pieces` writes them."""
        from .kernels import scatter_vectors  # warp at import: only with the sim extra

        newton = self.newton
        self.scatter_vectors = scatter_vectors
        self.model = builder.finalize(device=self.device)
        self.pin_index = self.wp.array(
            np.asarray(attached, np.int32), dtype=self.wp.int32, device=self.device
        )
        self.air = (
            AirDrag(self.wp, self.model, coefficient=config.air_drag, device=self.device)
            if config.air_drag > 0
            else None
        )
        self.viscosity = (
            ClothViscosity(
                self.wp,
                self.model,
                viscosity=config.cloth_viscosity,
                pinned=self.pin_index,
                device=self.device,
            )
            if config.cloth_viscosity > 0
            else None
        )
        self.model.soft_contact_ke = config.contact_ke
        self.model.soft_contact_kd = config.contact_kd
        self.model.soft_contact_mu = config.contact_mu
        self.pipeline = newton.CollisionPipeline(self.model, soft_contact_gap=config.contact_gap)
        self.contacts = self.pipeline.contacts()
        self.solver = newton.solvers.SolverVBD(
            self.model, iterations=config.iterations, integrate_with_external_rigid_solver=True
        )
        self.states = (self.model.state(), self.model.state())
        self.control = self.model.control()
        self.attached = attached
        self.pin_values = self.wp.empty(len(attached), dtype=self.wp.vec3, device=self.device)
        self.parity = 0  # states[parity] holds the current positions
        self.graphs: list = [None, None]
        self.arm_shapes = arm_shapes
        self.arm_contacts = [True] * len(arm_shapes)
        self.collide_particles = int(newton.ShapeFlags.COLLIDE_PARTICLES)
        self.piece_meshes = [builder.shape_source[s].mesh for s in piece_shapes]
        if piece_shapes:
            self._pad_piece_bounds(piece_shapes)

    def _pad_piece_bounds(self, piece_shapes: list[int]) -> None:
        """Widen each piece's box in its body's frame (the contact search culls by it, computed at
        finalize from the rest pose) by what skinning can move the piece's skin past its bone."""
        lower, upper = (
            self.model.shape_collision_aabb_lower.numpy(),
            self.model.shape_collision_aabb_upper.numpy(),
        )
        lower[piece_shapes] -= PIECE_BOUNDS_PAD_M
        upper[piece_shapes] += PIECE_BOUNDS_PAD_M
        self.model.shape_collision_aabb_lower.assign(lower)
        self.model.shape_collision_aabb_upper.assign(upper)

    def set_pieces(self, local_from: np.ndarray, local_to: np.ndarray, dt: float) -> None:
        """Reshape the skinned pieces for the coming frame: every piece's vertices (N, 3), concatenated
        in :attr:`piece_meshes`' order, in its body's frame at the frame's end, and the velocity that
        moves them there from ``local_from`` over ``dt`` (the contact's friction reads it)."""
        start = 0
        velocity = (local_to - local_from) / dt
        for mesh in self.piece_meshes:
            stop = start + mesh.points.shape[0]
            mesh.points.assign(local_to[start:stop])
            mesh.velocities.assign(velocity[start:stop])
            mesh.refit()
            start = stop

    @property
    def arm_contact(self) -> bool:
        """Whether the (first) instance's arms touch the cloth."""
        return self.arm_contacts[0]

    def set_arm_contact(self, on: bool, instance: int = 0) -> None:
        """Let an instance's arm capsules touch the cloth or not (see :meth:`set_arm_contacts`)."""
        wanted = list(self.arm_contacts)
        wanted[instance] = on
        self.set_arm_contacts(wanted)

    def set_arm_contacts(self, wanted: list[bool]) -> None:
        """Let each instance's arm capsules touch the cloth or not, in one write of the shape flags.
        The contact kernels read the shape flags on every launch (captured graphs included) and
        VBD's candidate tables stay valid."""
        changed = [i for i, on in enumerate(wanted) if on != self.arm_contacts[i]]
        if not changed:
            return
        flags = self.model.shape_flags.numpy()
        for i in changed:
            arms = self.arm_shapes[i]
            flags[arms] = (
                flags[arms] | self.collide_particles if wanted[i] else flags[arms] & ~self.collide_particles
            )
            self.arm_contacts[i] = wanted[i]
        self.model.shape_flags.assign(flags)

    def _substep(self, parity: int, dt: float) -> None:
        state_in, state_out = self.states[parity], self.states[1 - parity]
        self.pipeline.collide(state_in, self.contacts)
        self.solver.step(state_in, state_out, self.control, self.contacts, dt)
        if self.air is not None:
            self.air.apply(state_out, dt)
        if self.viscosity is not None:
            self.viscosity.apply(state_out, dt)

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

    def step_frame(
        self,
        body_from: np.ndarray,
        body_to: np.ndarray,
        pin_from: np.ndarray,
        pin_to: np.ndarray,
        dt: float,
        substeps: int,
        pieces: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """Advance one frame; body_* (C, 7) [p, q(xyzw)] of every instance's capsules, pin_* (A, 3)
        the positions of ``attached``, written on the device each substep; ``pieces``: the skinned
        pieces' vertices from and to (:meth:`set_pieces`). Returns every particle's positions (V, 3)."""
        if pieces is not None:
            self.set_pieces(pieces[0], pieces[1], dt)
        if len(self.attached) and self.viscosity is not None:
            # the pins move from pin_from to pin_to at one velocity over the frame
            self.viscosity.set_pinned_velocity((pin_to - pin_from) / dt)
        for k in range(substeps):
            t0, t1 = k / substeps, (k + 1) / substeps
            state_in, state_out = self.states[self.parity], self.states[1 - self.parity]
            # The solver derives body contact velocities from the old (input) and new (output) poses.
            for state, t in ((state_in, t0), (state_out, t1)):
                pose = np.concatenate(
                    [
                        (1 - t) * body_from[:, :3] + t * body_to[:, :3],
                        nlerp(body_from[:, 3:], body_to[:, 3:], t),
                    ],
                    1,
                )
                state.body_q.assign(pose.astype(np.float32))
            if len(self.attached):
                self.pin_values.assign(((1 - t1) * pin_from + t1 * pin_to).astype(np.float32))
                self.wp.launch(
                    self.scatter_vectors,
                    dim=len(self.attached),
                    inputs=[self.pin_values, self.pin_index],
                    outputs=[state_in.particle_q],
                    device=self.device,
                )
            self._run_substep(dt / substeps)
        return self.states[self.parity].particle_q.numpy().copy()

    def current(self) -> np.ndarray:
        return self.states[self.parity].particle_q.numpy()

    def speeds(self) -> np.ndarray:
        return np.linalg.norm(self.states[self.parity].particle_qd.numpy(), axis=1)


class ClothScene(SteppedScene):
    """A newton model of one garment and the capsule body, stepped frame by frame."""

    def __init__(
        self,
        garment: GarmentMesh,
        start_vertices: np.ndarray,
        half_lengths: np.ndarray,
        body: BodyModel,
        config: SimSettings,
        pieces: list | None = None,
    ):
        wp, newton = import_newton()
        self.wp, self.newton, self.config = wp, newton, config
        self.device = resolve_device(wp, config.device)
        builder, shapes = instance_builder(garment, start_vertices, half_lengths, body, config, pieces=pieces)
        add_ground(builder, config)
        self._finish(
            builder,
            config,
            [[s for c in arms_off_capsules(body) for s in shapes[c]]],
            garment.attached,
            [shapes[c][0] for c, _, _ in pieces or ()],
        )
