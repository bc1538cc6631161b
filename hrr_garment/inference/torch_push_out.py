"""The collision push-out and its strain limit (:mod:`hrr_garment.inference.collision`,
:mod:`hrr_garment.inference.strain_limit`) as a PyTorch module that ONNX can hold, the last stage of
:class:`~.torch_step.StreamStep`: the push's round under a conditional (ONNX ``If``, skipped when
nothing is within the margin) and its projections as a loop (ONNX ``Loop``, while a point is
inside, the body measured in it again where a step moved the cloth), the strain limit's passes as a
loop while a character still has an over-long edge, each character stopping on its own, as the
package stops each frame. With the push in the garment's subspace first where the run asks for it
(:class:`~.torch_subspace_push.SubspacePushStage`).

The body it pushes out of is the capsules posed by FK, or the mesh the viewer sees: a character's
skinned mesh measured by its collider's graph (:class:`~hrr_garment.models.skin_collider_graph.
SkinColliderGraph`, the same collider the package's kernel measures), the rest unchanged, as the
package's push-out against a :class:`~.visible_push.PosedSkin` is its capsule push with the other
distance. Beyond the margin of every hull (the capsules grown to hold the posed skin,
:mod:`.torch_skin_hulls`) the hulls' distance is the distance, as the package's; within it the graph
measures every vertex against the skin, without the package's flood of cells and winding test: the
same push wherever the collider's side is right, which its pseudonormals make it but at points
whose nearest face in the pose its grid does not list (a few in a hundred thousand: there the
package's winding number decides, and the graph can push what the package leaves). The skin is
measured at the vertices within that margin alone, and again only where a round moved them, each
character's skin posed once a push; still about 15 x the capsules' stage in onnxruntime (the dress
on anny's average body, docs/benchmarks.md), for want of the package's broad phase."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..models.graph_loops import exportable_cond, exportable_while
from .collision import PROJECTIONS, RELEASE_PASSES, PushOutSettings
from .limb_release import RELEASED_RADIUS, limb_capsules
from .torch_capsules import (
    capsule_depths,
    capsule_distance_within,
    per_point,
    point_capsule_distance,
)
from .torch_ops import constant
from .torch_strain_limit import StrainLimitStage
from .torch_subspace_push import SubspacePushStage


class PushOutStage(nn.Module):
    """World vertices (N, V, 3) pushed out of the body's capsules posed by FK, then their edges
    stretched by the push limited (:func:`~hrr_garment.inference.collision.push_out` with
    :func:`~hrr_garment.inference.strain_limit.limit_push_strain`)."""

    def __init__(
        self,
        capsules,
        smoothing,
        *,
        limits,
        settings: PushOutSettings,
        strain_passes: int = 60,
        skin: nn.Module | None = None,
        hulls: nn.Module | None = None,
    ):
        super().__init__()
        if skin is not None and settings.subspace is not None:
            raise ValueError(
                "the torch step's subspace push measures capsules (the package's measures the skin too): "
                "with push='subspace' in an ONNX graph or on a device, ask for push_body='capsules'"
            )
        if limits.body_of_frame is not None:
            raise ValueError("a step's push-out stage is of one body: give it that body's limits")
        self.skin = skin  # the visible mesh's collider graph, measured instead of the capsules
        self.hulls = hulls  # its hulls (.torch_skin_hulls): the skin measured only within the margin of one
        joints, a, b, radii = capsules
        self.joints = [int(j) for j in joints]
        constant(self, "cap_a", a)
        constant(self, "cap_b", b)
        constant(self, "radii", radii)
        self.settings = settings
        self.subspace = (
            None if settings.subspace is None else SubspacePushStage(settings.subspace, settings.margin)
        )
        # the smoothing's row-normalised adjacency as (row, column, weight) triplets: a gather, a
        # product and a scatter-add (ONNX has no sparse product)
        smoothing = smoothing.tocoo()
        constant(self, "smooth_rows", smoothing.row, dtype=torch.int64)
        constant(self, "smooth_cols", smoothing.col, dtype=torch.int64)
        constant(self, "smooth_weights", smoothing.data[:, None])  # (nnz, 1): over the characters
        # the neighbour-follow's padded 1-ring and each slot's drop (slope x rest distance); the
        # padding's infinite drop as a large finite one, which never wins either
        constant(self, "ring", limits.ring, dtype=torch.int64)
        constant(
            self, "ring_drop", np.minimum(settings.follow_slope * limits.ring_length, 1e6)[..., None]
        )  # (V, D, 1)
        constant(self, "limbs", limb_capsules(), dtype=torch.int64)  # the capsules that may let go
        self.strain = StrainLimitStage(
            limits, max_strain=settings.max_strain, stretch_slack=settings.stretch_slack, passes=strain_passes
        )

    @classmethod
    def of_visible(cls, visible, smoothing, *, limits, settings: PushOutSettings) -> "PushOutStage":
        """The stage that pushes out of the mesh a :class:`~.visible_push.VisibleCollider` measures:
        its collider's graph within the margin of its hulls (the capsules of its body grown)."""
        from ..models.skin_collider_graph import SkinColliderGraph
        from .torch_skin_hulls import SkinHulls

        body = visible.body
        return cls(
            (*body.ends, body.radii),
            smoothing,
            limits=limits,
            settings=settings,
            skin=SkinColliderGraph(visible.collider),
            hulls=SkinHulls(visible.envelope),
        )

    def distance(
        self,
        p: torch.Tensor,
        a: torch.Tensor,
        b: torch.Tensor,
        radii: torch.Tensor | None = None,
        within: float | None = None,
        surface: tuple = (),
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Signed distances (N, V) to the union of capsules and the nearest one's outward normals,
        (N, V, 3), measured where the distance is under ``within`` (the push's margin by default:
        where a push reads them) and zero elsewhere (:func:`capsule_distance_within`); ``p``, ``a``,
        ``b`` relative to the pelvis keep them to metres. On the visible mesh, ``a`` and ``b`` are
        the joints' moves (:meth:`forward`) and the distance and normal the skin's within the
        margin of its hulls (beyond it the hulls' distance and a zero normal), ``surface`` the
        characters' posed skin (:meth:`~.SkinColliderGraph.surface`).
        ``radii``: (N, 1, C) each character's (a limb let go of: very negative; None: the body's)."""
        if self.skin is not None:
            beyond = self._beyond(p, radii)
            near = beyond <= self.settings.margin
            return self._measured(p, near, beyond, torch.zeros_like(p), a, b, radii, *surface)[1:]
        within = self.settings.margin if within is None else within
        radii = self.radii if radii is None else radii
        return capsule_distance_within(p, a, b, radii=radii, within=within)

    def _beyond(self, p: torch.Tensor, radii: torch.Tensor) -> torch.Tensor:
        """(N, V) on the visible mesh, the hulls' distance, as the package's push-out takes it beyond
        the margin of every hull (``radii``: the hulls' ends and radii, (N, C, 7)); the skin is measured
        within it alone (their normals never read: no push moves a point farther than the margin).
        Without hulls 0: every point measured."""
        if self.hulls is None:
            return torch.zeros_like(p[..., 0])
        return capsule_depths(p, radii[..., :3], radii[..., 3:6], radii=radii[..., 6][:, None])

    def smooth(self, disp: torch.Tensor) -> torch.Tensor:
        """One pass of the mean over each vertex's neighbours, vertex-major (V, ...)."""
        terms = torch.index_select(disp, 0, self.smooth_cols) * self.smooth_weights[..., None]
        return torch.zeros_like(disp).index_add(0, self.smooth_rows, terms)

    def push(
        self, p: torch.Tensor, a: torch.Tensor, b: torch.Tensor, radii: torch.Tensor, *surface: torch.Tensor
    ) -> torch.Tensor:
        """``surface``: on the visible mesh, the characters' posed skin's tensors (made once a push).

        The body measured (:meth:`distance`), the rounds of push-and-spread, then one loop (an ONNX
        ``Loop`` when exporting, the same steps in Python when running) that measures the body again
        at the vertices the step before moved and projects those still inside out to the margin, at
        most :data:`PROJECTIONS` times, while a point is inside. On the visible mesh the first measure
        and the rounds are that loop's first steps too (:meth:`_skin_push`)."""
        if self.skin is not None:
            return self._skin_push(p, a, b, radii, *surface)
        d, n = self.distance(p, a, b, radii)
        pending = d < 0  # what a push without rounds projects first
        for r in range(self.settings.rounds):
            if r:  # the round before moved these
                p, d, n = self._measured(p, pending, d, n, a, b, radii)
            p, pending = exportable_cond(
                (d < self.settings.margin).any(), self._round, _unmoved, operands=(p, d, n)
            )
        state = (torch.zeros((), dtype=torch.int64, device=p.device), p, d, n, pending)

        def project(k, p, d, n, pending):
            p, d, n = self._measured(p, pending, d, n, a, b, radii)
            projected, inside = self._projected(p, d, n, k < PROJECTIONS)
            return k + 1, projected, d, n, inside

        return exportable_while(_pending, project, state)[1]

    def _skin_push(self, p, a, b, radii, *surface) -> torch.Tensor:
        """:meth:`push` on the visible mesh, its every measure of the skin in one loop: the first
        step measures the points within the margin of a hull (beyond it the hull's distance stands),
        the rounds follow it, each measuring what the one before moved, then the projections. Each
        step computes a round and a projection and keeps the one its count asks for (a conditional
        inside the loop does not export): the skin's graph is then traced once, not once before the
        loop and again inside it, which took a quarter of a character's step's export."""
        beyond = self._beyond(p, radii)
        rounds = self.settings.rounds
        state = (
            torch.zeros((), dtype=torch.int64, device=p.device),
            p,
            beyond,
            torch.zeros_like(p),
            beyond <= self.settings.margin,
        )

        def step(k, p, d, n, pending):
            p, d, n = self._measured(p, pending, d, n, a, b, radii, *surface)
            if not torch.compiler.is_compiling():  # running: the step its count asks for alone
                p, moved = (
                    self._round(p, d, n) if k < rounds else self._projected(p, d, n, k < rounds + PROJECTIONS)
                )
                return k + 1, p, d, n, moved
            pushed, spread_moved = self._round(p, d, n)
            projected, inside = self._projected(p, d, n, k < rounds + PROJECTIONS)
            spread = k < rounds
            return (
                k + 1,
                torch.where(spread, pushed, projected),
                d,
                n,
                (spread & spread_moved) | (~spread & inside),  # onnxruntime has no Where of booleans
            )

        return exportable_while(_pending, step, state)[1]

    def _projected(self, p, d, n, more: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The points inside moved out to the margin along their normals where ``more`` projections
        remain (a projection moves only points inside, so a point outside never moves, nor comes
        inside) -> the points and the ones it moved."""
        inside = (d < 0) & more
        rows = torch.nonzero(inside.reshape(-1))[:, 0]
        lift = (self.settings.margin - torch.index_select(d.reshape(-1), 0, rows))[:, None]
        moved = torch.index_select(p.reshape(-1, 3), 0, rows) + lift * torch.index_select(
            n.reshape(-1, 3), 0, rows
        )
        return p.reshape(-1, 3).index_copy(0, rows, moved).reshape(p.shape), inside

    def _round(self, p, d, n) -> tuple[torch.Tensor, torch.Tensor]:
        """A push along the normals, spread to the neighbours, never below what is needed -> the
        points and the vertices it moved (N, V), whose distances no longer stand. In (V, 3, N): a
        vertex's rows whole for the smoothing's gathers and scatter-adds, and no product broadcast
        over a last axis of 3 (which onnxruntime runs an element triple at a time). Nothing within
        the margin: nothing moves."""
        need = torch.clamp(self.settings.margin - d, min=0.0).transpose(
            0, 1
        )  # vertex-major, as smooth takes it
        if self.settings.follow:
            normals = n.transpose(0, 1)
            for _ in range(self.settings.follow):
                need, normals = self._follow(need, normals)
            normals = normals.permute(0, 2, 1)  # (V, 3, N)
        else:  # in one move of an axis (onnxruntime swaps the last two of (V, N, 3) 30 x slower)
            normals = n.permute(1, 2, 0)
        hit = need > 0
        disp = need[:, None] * normals
        for _ in range(self.settings.smooth):
            disp = self.smooth(disp)
            short = torch.where(
                hit, torch.clamp(need - (disp * normals).sum(1), min=0.0), torch.zeros_like(need)
            )
            disp = disp + short[:, None] * normals
        # the mask laid out as the projection's (a conditional's two branches must agree)
        return p + disp.permute(2, 0, 1), (disp != 0).any(1).transpose(0, 1).contiguous()

    def _measured(self, p, moved, d, n, a, b, radii, *surface):
        """``p`` with its distances ``d`` (N, V) to the body and normals ``n`` (N, V, 3) measured
        again at the vertices ``moved`` (N, V) alone: a push moves a few vertices of a frame, and
        measuring every vertex of every character again after it cost most of a crowd's push-out
        in onnxruntime. The same distances (each point's depends on it and its own character
        alone)."""
        rows = torch.nonzero(moved.reshape(-1))[:, 0]  # flat (character x vertex)
        character = torch.div(rows, p.shape[1], rounding_mode="floor")
        points = torch.index_select(p.reshape(-1, 3), 0, rows)
        dk, nk = self._point_distance(points, self._per_point(character, a, b, radii, *surface))
        d = d.reshape(-1).index_copy(0, rows, dk).reshape(d.shape)
        return p, d, n.reshape(-1, 3).index_copy(0, rows, nk).reshape(n.shape)

    def _per_point(self, character, a, b, radii, *surface) -> tuple:
        """The body's operands of each point's ``character`` (K,), as :meth:`_point_distance` takes
        them: its capsules, or its character with the crowd's joint moves and its hulls."""
        if self.skin is None:
            return per_point(character, a, b, radii=radii[:, 0])
        return character, a, b, torch.index_select(radii, 0, character), surface

    def _point_distance(self, points, own: tuple) -> tuple[torch.Tensor, torch.Tensor]:
        """(K,) distances and (K, 3) normals of points (K, 3), each of its own character (``own``:
        :meth:`_per_point`); on the skin, beyond the margin of every hull of its character the
        hulls' distance, as :meth:`distance` takes it."""
        if self.skin is None:
            return point_capsule_distance(points, own)
        character, rot, trans, hull, surface = own
        d, n = self.skin.query_rows(points, character, rot, trans, surface=surface)
        if self.hulls is None:
            return d, n
        beyond = capsule_depths(points[:, None], hull[..., :3], hull[..., 3:6], radii=hull[..., 6][:, None])[
            :, 0
        ]
        far = beyond > self.settings.margin
        return torch.where(far, beyond, d), torch.where(far[:, None], torch.zeros_like(n), n)

    def _follow(self, need: torch.Tensor, normals: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """One pass of the neighbour-follow (:func:`~hrr_garment.inference.collision.follow_pushes`),
        vertex-major: each vertex at least its neighbours' push less the drop, in the direction of the
        neighbour that sets it (the first of equals; the first pass starts from the normals of the
        vertices that need a push, zero elsewhere, which nothing reads where the push is 0)."""
        cand = need[self.ring] - self.ring_drop  # (V, D, N)
        best, slot = cand.max(1)
        better = best > need
        source = torch.gather(self.ring, 1, slot)  # (V, N): the neighbour that sets the push
        characters = torch.arange(need.shape[1], device=need.device)[None].expand_as(source)
        return torch.where(better, best, need), torch.where(
            better[..., None], normals[source, characters], normals
        )

    def forward(
        self,
        vertices: torch.Tensor,
        rotations: torch.Tensor,
        positions: torch.Tensor,
        heading: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> torch.Tensor:
        """``heading``: each frame's body-frame yaw as (cosines, sines), which the subspace push needs."""
        centre = positions[:, :1]  # (N, 1, 3): the pelvis
        p = vertices - centre
        radii = self.radii + torch.zeros_like(p[:, :1, :1])  # (N, 1, C): each character's
        if self.skin is not None:  # the joints' moves from the rest pose, about the pelvis (the
            # skin's weights sum to 1, so the posed skin moves with the points)
            a, trans = self.skin.moves(rotations, positions)
            trans = trans - centre
            surface = self.skin.surface(a, trans)  # the skins posed once, for every measure of the push
            if self.hulls is not None:  # the hulls about the pelvis, carried where radii go
                ca, cb = self._capsule_ends(rotations, positions, centre)
                hull = self.hulls(surface.posed, ca, cb, self.radii)
                radii = torch.cat([ca, cb, hull[..., None]], -1)  # (N, C, 7)
            return self.strain(self.push(p, a, trans, radii, *surface) + centre, vertices)
        a, b = self._capsule_ends(rotations, positions, centre)
        if self.subspace is not None:
            if heading is None:
                raise ValueError("the subspace push needs each frame's heading (the body frame's yaw)")
            reach = self.subspace.reach  # its normals read within the margin and its clearance
            p = self.subspace(p, a, b, heading, lambda q, a, b: self.distance(q, a, b, radii, reach))
            vertices = (
                p + centre
            )  # the limit's reference: the frame as the mesh push gets it, as the kernel's
        pushed = self.push(p, a, b, radii)
        out = self.strain(pushed + centre, vertices)
        if not self.settings.release_limbs or self.subspace is not None:
            return out
        for _ in range(RELEASE_PASSES):  # collision.push_out's: a torn character pushed again without
            # the limb capsules within the margin of a vertex the limit moved, where the push took it
            repaired = (out != pushed + centre).any(-1)  # (N, V)
            held = self._held_limbs(repaired, p, a, b, radii)  # (N, C)
            radii = torch.where(held[:, None], torch.full_like(radii, RELEASED_RADIUS), radii)
            operands = (p, a, b, radii, centre, vertices, pushed, out)
            pushed, out = exportable_cond(held.any(), self._released, _kept, operands=operands)
        return out

    def _capsule_ends(
        self, rotations: torch.Tensor, positions: torch.Tensor, centre: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The capsules' ends (N, C, 3) posed by FK, about the pelvis ``centre`` (N, 1, 3)."""
        rot, pos = rotations[:, self.joints], positions[:, self.joints]
        a = pos - centre + (rot @ self.cap_a[..., None])[..., 0]
        return a, pos - centre + (rot @ self.cap_b[..., None])[..., 0]

    def _held_limbs(self, repaired, p, a, b, radii) -> torch.Tensor:
        """(N, C) the limb capsules within the margin of a repaired vertex (:mod:`.limb_release`)."""
        limbs = self.limbs
        la, ab = a[:, limbs], b[:, limbs] - a[:, limbs]  # (N, L, 3)
        rel = p[:, :, None] - la[:, None]  # (N, V, L, 3)
        s = torch.clamp(
            (rel * ab[:, None]).sum(-1) / torch.clamp((ab * ab).sum(-1), min=1e-12)[:, None], 0.0, 1.0
        )
        gap = torch.sqrt(((rel - s[..., None] * ab[:, None]) ** 2).sum(-1)) - radii[:, :, limbs]
        near = ((gap < self.settings.margin) & repaired[..., None]).any(1)  # (N, L)
        return torch.zeros_like(radii[:, 0], dtype=torch.bool).index_copy(1, limbs, near)

    def _released(self, p, a, b, radii, centre, vertices, pushed, out):
        """The characters that let go of a limb pushed again (the others as they were)."""
        again = self.push(p, a, b, radii)
        limited = self.strain(again + centre, vertices)
        moved = (radii < self.radii).any(-1)  # (N, 1): a character that let go of a limb
        return torch.where(moved[..., None], again, pushed), torch.where(moved[..., None], limited, out)


def _pending(*state) -> torch.Tensor:
    """Whether the last of a push loop's ``state``, its mask of points still to measure, has any."""
    return state[-1].any()


def _unmoved(p: torch.Tensor, d: torch.Tensor, n: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The branch of a round with nothing within the margin (a conditional's outputs may not alias
    its inputs)."""
    return p.clone(), torch.zeros_like(d, dtype=torch.bool)


def _kept(p, a, b, radii, centre, vertices, pushed, out):
    """The branch with no limb let go (a conditional's outputs may not alias its inputs)."""
    return pushed.clone(), out.clone()
