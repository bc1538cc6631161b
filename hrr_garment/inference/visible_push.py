"""The body the push-out pushes the cloth out of, when it is the mesh the viewer sees.

    posed = PosedSkin.of(VisibleCollider.of(body, skin), motion)   # a clip on one body
    vertices, report = push_out(vertices, motion, faces, body=posed)

:func:`~.collision.push_out` takes a :class:`PosedSkin` where it takes capsules: every garment
vertex is measured first against the skin's hulls (:mod:`hrr_garment.body.skin_envelope`: the body's
capsules widened frame by frame to hold their pieces of the posed skin), and those within the
push's margin of a hull, or inside one, against the skin itself
(:mod:`hrr_garment.body.skin_collider`: the exact signed distance to the skinned mesh's posed
triangles), except those the frame's broad phase finds farther than the margin from the skin and
outside it (:mod:`hrr_garment.body.skin_cells`, where the mesh is closed): they get ``FAR_AWAY``.
A vertex farther than the margin from every hull is farther than that from the skin, so the push
moves exactly the vertices the skin alone would have it move. The kernel (``hrr_garment.native``)
does the same per frame; :meth:`PosedSkin.distance` is the reference.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..body.capsules import BodyModel, frames_signed_distance
from ..body.mesh_distance import winding_inside, within_reach
from ..body.skin_cells import SkinCells, closed_mesh, skin_cells
from ..body.skin_collider import SkinCollider
from ..body.skin_collider_store import stored_skin_collider
from ..body.skin_envelope import SkinEnvelope
from ..body.skinned_body import SkinnedBody
from ..motion.motion import Motion
from .collision import PosedCapsules


@dataclass(frozen=True)
class VisibleCollider:
    """One body's visible mesh as the push-out measures it: its capsules (fitted to the mesh), the
    skin's hulls over them and the skin's collider (built once a body: seconds for an anny body)."""

    body: BodyModel
    envelope: SkinEnvelope  # the capsules grown per frame to hold the skin
    collider: SkinCollider

    @classmethod
    def of(cls, body: BodyModel, skin: SkinnedBody) -> "VisibleCollider":
        return cls(body, SkinEnvelope.of(skin, body), stored_skin_collider(skin))

    @cached_property
    def kernel(self):
        """The collider in the C kernel's layout (None without a C compiler)."""
        from ..native import load_kernel
        from ..native.skin import SkinKernel

        lib = load_kernel()
        return None if lib is None else SkinKernel(self.collider, lib)

    def skinned(
        self,
        rotations: np.ndarray,
        positions: np.ndarray,
        capsules: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """For (T, J, 3, 3) global rotations and (T, J, 3) joint positions: the joints' moves from the
        rest pose (T, J, 3, 3) and (T, J, 3), the mesh posed by them (T, V, 3) and, given the frames'
        capsule ends (a, b (T, C, 3)), the skin's hulls' radii (T, C)
        (:mod:`~hrr_garment.body.skin_envelope`: each capsule grown to hold its pieces of the posed
        skin, never narrower): by the kernel where there is one, frames in parallel, as the push-out
        poses it, and the hulls by the envelope's ``growth`` (the kernel's reference) without it."""
        body = self.collider.body
        rot, trans = body.joint_transforms(rotations, positions)
        rot, trans = np.ascontiguousarray(rot), np.ascontiguousarray(trans)
        if self.kernel is None:
            posed = body.pose(rotations, positions)
            if capsules is None:
                return rot, trans, posed, None
            growth = self.envelope.growth(rotations, positions, posed=posed)
            return rot, trans, posed, np.maximum(self.body.radii + growth, self.body.radii)
        from ..native import default_threads

        ends = None if capsules is None else (*capsules, self.body.radii)
        return rot, trans, *self.kernel.hulls(rot, trans, ends, self.pieces, threads=default_threads())

    @cached_property
    def pieces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The envelope's pieces as the kernel takes them: corners (P, 3) int32, bary (P, 3), capsule
        (P,) int32."""
        e = self.envelope
        return (
            np.ascontiguousarray(e.corners, np.int32),
            np.ascontiguousarray(e.bary, np.float64),
            np.ascontiguousarray(e.capsule, np.int32),
        )

    def posed(self, rotations: np.ndarray, positions: np.ndarray) -> np.ndarray:
        """(T, V, 3) the mesh posed (:meth:`skinned`)."""
        return self.skinned(rotations, positions)[2]

    @cached_property
    def closed(self) -> bool:
        """Whether the visible mesh is closed (the broad phase's outside needs it)."""
        return closed_mesh(self.collider.body.faces)

    def cells(self, rotations: np.ndarray, positions: np.ndarray, margin: float) -> SkinCells | None:
        """One frame's broad phase (None on an open mesh): the kernel's where there is one (equal to
        :func:`~hrr_garment.body.skin_cells.skin_cells`, its reference, on the same posed mesh)."""
        if not self.closed:
            return None
        posed = self.posed(rotations[None], positions[None])[0]
        if self.kernel is None:
            return skin_cells(posed, self.collider.body.faces, margin=margin, cell=CELL_M)
        return SkinCells(*self.kernel.cells(posed, margin, CELL_M), CELL_M)


CELL_M = 0.02  # the reference's cull's cells (docs/bodies.md, "The push-out against the visible mesh")
COLUMN_M = 0.02  # the kernel's broad phase's columns (the same section)
FAR_AWAY = 1e30  # the distance of a point the broad phase finds far outside the skin (the kernel's)

_BUILT: dict[tuple[int, int], tuple[BodyModel, SkinnedBody, VisibleCollider]] = {}
KEPT_COLLIDERS = 8  # bodies whose colliders a process keeps (an anny body's: about 15 MB)


def visible_collider(body: BodyModel, skin: SkinnedBody) -> VisibleCollider:
    """:meth:`VisibleCollider.of`, built once a body in a process (seconds each): keyed by the two
    objects' identity, which :func:`~hrr_garment.body.skinned_body.visible_body` keeps for a body."""
    key = (id(body), id(skin))
    if key not in _BUILT:
        while len(_BUILT) >= KEPT_COLLIDERS:
            _BUILT.pop(next(iter(_BUILT)))
        _BUILT[key] = (body, skin, VisibleCollider.of(body, skin))  # the objects held: ids stay theirs
    return _BUILT[key][2]


@dataclass(frozen=True)
class PosedSkin:
    """Frames of visible bodies posed: frame t is ``bodies[which[t]]`` in the pose of the joints'
    global rotations and positions (what :func:`~.collision.push_out` takes for ``body``)."""

    bodies: tuple[VisibleCollider, ...]
    which: np.ndarray  # (T,) int64
    rotations: np.ndarray  # (T, J, 3, 3) the joints' global rotations
    positions: np.ndarray  # (T, J, 3)
    hulls: PosedCapsules  # the capsules' ends (T, C, 3) and each frame's hull radii (T, C)
    # each frame's body's skin as the hulls were made from it (VisibleCollider.skinned), kept for the
    # kernel, which would otherwise pose it again: the joints' moves (T, J, 3, 3) and (T, J, 3), and
    # per frame the posed mesh (V, 3)
    moves: tuple[np.ndarray, np.ndarray]
    skins: tuple[np.ndarray, ...]

    @classmethod
    def of(cls, visible: VisibleCollider, motion: Motion) -> "PosedSkin":
        """A clip on one body."""
        return cls.of_frames((visible,), np.zeros(motion.num_frames, np.int64), motion)

    @classmethod
    def of_frames(cls, bodies: tuple[VisibleCollider, ...], which: np.ndarray, poses: Motion) -> "PosedSkin":
        """Frame t of ``poses`` on ``bodies[which[t]]`` (a crowd's characters, one frame each)."""
        rot, pos = np.asarray(poses.global_rotations), np.asarray(poses.joint_positions)
        a = np.empty((len(which), len(bodies[0].body.capsules), 3))
        b, radii = np.empty_like(a), np.empty(a.shape[:2])
        moves = np.empty(rot.shape), np.empty(pos.shape)
        skins: list = [None] * len(which)
        for k, visible in enumerate(bodies):
            rows = np.flatnonzero(which == k)
            if not len(rows):
                continue
            if len(visible.body.capsules) != a.shape[1]:
                raise ValueError("every body of a push-out needs the same number of capsules")
            a[rows], b[rows] = visible.body.pose(rot[rows], pos[rows])
            # the hulls never narrower than the capsules (inside the body: the union keeps the body's
            # inside in it), and a capsule that holds no piece of the skin as it is
            moves[0][rows], moves[1][rows], posed, radii[rows] = visible.skinned(
                rot[rows], pos[rows], capsules=(a[rows], b[rows])
            )
            for i, t in enumerate(rows):
                skins[t] = posed[i]
        return cls(
            tuple(bodies),
            np.asarray(which, np.int64),
            rot,
            pos,
            PosedCapsules(a, b, radii),
            moves,
            tuple(skins),
        )

    def distance(
        self, points: np.ndarray, rows: slice | np.ndarray, margin: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """(t, V) signed distances and (t, V, 3) outward normals of points (t, V, 3) of frames
        ``rows`` (a slice or indices): the skin's where within ``margin`` of a hull or inside one,
        else the hulls' (more than the margin, as the skin's is there), and ``FAR_AWAY`` (normal 0)
        where the point is farther than the margin from the skin and outside it (the winding
        number), on a closed mesh (the cells the broad phase's flood reaches are, the others are
        measured exactly against every triangle): the push-out kernel's reference, the skin
        measured by its own kernel where there is one (equal to its reference to 1e-15)."""
        a, b, radii = self.hulls.a[rows], self.hulls.b[rows], self.hulls.radii[rows]
        d, n = frames_signed_distance(points, a, b, radii=radii)
        for i, t in enumerate(np.arange(len(self.which))[rows]):
            near = np.flatnonzero(d[i] <= margin)
            visible = self.bodies[self.which[t]]
            cells = visible.cells(self.rotations[t], self.positions[t], margin) if len(near) else None
            if cells is not None:
                far = cells.far(points[i, near])
                rest = near[~far]  # the band and the cells the flood did not reach: measured exactly
                if len(rest):
                    faces = visible.collider.body.faces
                    posed = self.skins[t]
                    clear = ~within_reach(points[i, rest], posed, faces, reach=margin)
                    clear[clear] = ~winding_inside(points[i, rest[clear]], posed, faces)
                    far[~far] = clear
                d[i, near[far]], n[i, near[far]] = FAR_AWAY, 0.0
                near = near[~far]
            if len(near):
                query = visible.collider.query if visible.kernel is None else visible.kernel.query
                d[i, near], n[i, near] = query(points[i, near], self.rotations[t], self.positions[t])
        return d, n

    def deeper_inside(self, points: np.ndarray, depth: float, margin: float) -> np.ndarray:
        """(T,) each frame's share of points (T, V, 3) more than ``depth`` inside the skin, as
        :meth:`distance` counts them within ``margin``, measuring only the points that deep inside a
        hull (the hulls hold the skin, so a point that deep in the skin is that deep in them), then,
        on a closed mesh, letting the broad phase take out those it finds outside and beyond the
        margin (where the collider's side is wrong, as the push-out's kernel does). The push-out's
        report of the cloth as it came where its kernel saw it only after the subspace push: a tenth
        of :meth:`distance`'s time. Without the kernel, :meth:`distance` itself."""
        if any(v.kernel is None for v in self.bodies):
            return (self.distance(points, slice(None), margin)[0] < -depth).mean(1)
        d, _ = frames_signed_distance(points, self.hulls.a, self.hulls.b, radii=self.hulls.radii)
        share = np.zeros(len(points))
        for t in range(len(points)):
            deep = np.flatnonzero(d[t] < -depth)
            if len(deep):
                share[t] = (
                    np.count_nonzero(self._skin_near(t, points[t, deep], margin) < -depth) / points.shape[1]
                )
        return share

    def frame_distance(self, t: int, points: np.ndarray, margin: float) -> np.ndarray:
        """(N,) signed distances of points (N, 3) to frame ``t``'s skin as :meth:`distance` measures
        them within ``margin``: the hulls' past the margin of every hull (they hold the skin), else
        :meth:`_skin_near`'s. Without the kernel, :meth:`distance` itself."""
        if self.bodies[self.which[t]].kernel is None:
            return self.distance(points[None], np.array([t]), margin)[0][0]
        rows, hulls = slice(t, t + 1), self.hulls
        d, _ = frames_signed_distance(points[None], hulls.a[rows], hulls.b[rows], radii=hulls.radii[rows])
        d = d[0]
        near = np.flatnonzero(d < margin)
        if len(near):
            d[near] = self._skin_near(t, points[near], margin)
        return d

    def _skin_near(self, t: int, points: np.ndarray, margin: float) -> np.ndarray:
        """(N,) the skin kernel's signed distances of points (N, 3) within ``margin`` of a hull of
        frame ``t`` or inside one, ``FAR_AWAY`` where the kernel calls a point nearer than the margin
        but the broad phase finds it beyond the margin and outside (on a closed mesh: where the
        collider's side is wrong, as the push-out's kernel does)."""
        visible = self.bodies[self.which[t]]
        d = visible.kernel.query_posed(points, self.moves[0][t], self.moves[1][t], self.skins[t])[0]
        near = np.flatnonzero(d < margin)
        if len(near) and visible.closed:
            d[near[visible.kernel.far_outside(self.skins[t], points[near], margin, COLUMN_M)]] = FAR_AWAY
        return d

    def native(self, *, measure_after: bool = False):
        """The frames as the kernel reads them (:class:`~hrr_garment.native.skin.PosedSkins`), with
        their broad phase's column width where the mesh is closed; ``measure_after``: the kernel
        measures a frame its strain limit moved again, for the report."""
        from ..native.skin import PosedSkins

        return PosedSkins(
            [v.kernel for v in self.bodies],
            self.which,
            moves=self.moves,
            skins=self.skins,
            closed=[v.closed for v in self.bodies],
            cell=COLUMN_M,
            measure_after=measure_after,
        )
