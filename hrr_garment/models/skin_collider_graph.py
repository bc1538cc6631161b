"""The collider of the body the viewer sees (:class:`~hrr_garment.body.skin_collider.SkinCollider`,
the numpy reference; ``hrr_garment.native.skin`` its C kernel) as a torch module that ONNX can
hold and autograd can differentiate: the same starts, fixed-point steps, face lists and sign rules,
in gathers, batched products and ``where``, with shapes that depend on no point's answer.

    graph = SkinColliderGraph(skin_collider(visible))            # float32; dtype=torch.float64 too
    distance, normal = graph(points, global_rotations, joint_positions)   # (N,), (N, 3)

Batched over B characters as well: points (B, N, 3) with (B, J, 3, 3) and (B, J, 3); or a crowd's
points as one list, each with its character (:meth:`SkinColliderGraph.query_rows`), so that a push
measures the points it asks about and no others.
``hrr_garment.export.skin_collider_onnx`` writes it as ONNX. What the reference does with
data-dependent shapes or loops, the graph does with fixed ones:

- the starts (the ``starts`` joints whose rigid guesses rank best, ties to the lower joint, as the
  reference's stable sort) by ``starts`` argmins (the first of equals), each taking its joint out;
- a joint's own weight at its guess, and the trilinear read of the skin weights, from one dense
  (nodes, J + 1) table (a node's four weights scattered onto its joints, its rest distance last):
  the eight rows a point reads gathered and summed by their shares at once;
- M(w)^-1 by the adjugate (``torch.linalg.solve`` has no ONNX form), as the C kernel does;
- each node's face list padded to the longest (at most ``max_faces``) with its first face: the
  nearest is unchanged (a repeated face is no nearer than itself; the first of equals wins, as in
  the reference), and every point measures the same number of faces a start.
- a point's starts that settled on one node list the same faces: each distinct node measured once
  (a list of (point, start) pairs), its answer copied to the others;
- each character's mesh posed once a query, with each face's corner, edges and their products
  (:meth:`SkinColliderGraph.surface`): every listed face ranked from those by two products a point
  and face, the nearest one's point then found again from its posed corners as the reference finds
  it (to rounding the same face; that one carries the gradient).

**Equal to the reference.** In float64, to rounding (1e-9 in the tests; measured on a limb bent up
to 135 degrees, a curled chain and an anny body in a dance, the distance within 1e-15 m, the
normal within 1e-10).
In float32 (tests/models/test_skin_collider_graph.py, the bound stated and tested): the distance
within 1 um of the reference's (0.31 um measured on an anny body) and on its side; the normal, a
millimetre or more off the skin, within 0.01 (0.003 measured) but where two faces lie equally
near within float32's rounding (a point deep in a bend: then the other face's normal, as right),
always pointing to a nearest point of the posed mesh. Nearer the skin than a millimetre the
normal (the gap's direction) is rounding's.

**Differentiable.** Off the surface, the distance's gradient with respect to the points is the
normal: the inverse skinning only chooses faces (its rest points feed nothing but indices and the
sign rules), so it runs detached, and the distance to the nearest point of a triangle has the unit
gap as its gradient. Gradients reach the joints' rotations and positions through the posed faces
(the whole body moved by d: each distance falls by normal . d).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from ..body.skin_collider import side_rules
from .graph_loops import exportable_while
from .torch_mesh import closest_in_plane, closest_on_triangles, cross, dot, pseudo_normals

MAX_POINTS = 1 << 40  # the most points one query takes (a bound for the exporter)


class SkinColliderGraph(nn.Module):
    """A :class:`~hrr_garment.body.skin_collider.SkinCollider`'s arrays as buffers (its rest mesh,
    weights, rest frames and grid) and its query as :meth:`forward`."""

    def __init__(self, collider, dtype: torch.dtype = torch.float32) -> None:
        super().__init__()
        body, settings = collider.body, collider.settings
        joints = body.weights.shape[1]
        self.settings, self.joints = settings, joints
        self.starts = min(settings.starts, joints)
        # each node's four weights scattered onto its J joints, its rest distance after them
        table = np.zeros((len(collider.distance), joints + 1))
        rows = np.arange(len(table))[:, None]
        np.add.at(table, (rows, collider.joints.astype(np.int64)), collider.weights.astype(np.float64))
        table[:, -1] = collider.distance
        real = {
            "rest": body.vertices,
            "skin": body.weights,
            "rest_rotations": body.rest_rotations,
            "rest_positions": body.rest_positions,
            "origin": collider.origin,
            "top": np.asarray(collider.shape, np.float64) - 1.0,
            "table": table,
        }
        for name, value in real.items():
            self.register_buffer(name, torch.as_tensor(np.asarray(value, np.float64), dtype=dtype))
        count = np.diff(collider.face_start)
        column = np.arange(count.max())  # at most max_faces
        listed = collider.face_start[:-1, None] + np.where(column < count[:, None], column, 0)
        self.register_buffer("face_table", torch.as_tensor(collider.face_list[listed], dtype=torch.int32))
        self.register_buffer("faces", torch.as_tensor(body.faces, dtype=torch.int64))
        self.register_buffer("neighbours", torch.as_tensor(collider.neighbours, dtype=torch.int64))
        self.register_buffer("shape", torch.as_tensor(collider.shape, dtype=torch.int64))
        # the eight nodes about a point, c = 4 c0 + 2 c1 + c2, as offsets of its base node's row (an
        # axis of one node: its only one)
        s = np.asarray(collider.shape, np.int64)
        offsets = [
            min((c >> 2) & 1, s[0] - 1) * s[1] * s[2]
            + min((c >> 1) & 1, s[1] - 1) * s[2]
            + min(c & 1, s[2] - 1)
            for c in range(8)
        ]
        self.register_buffer("corner_offsets", torch.tensor(offsets, dtype=torch.int64))

    def moves(
        self, global_rotations: torch.Tensor, joint_positions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Each joint's rigid move from the rest pose (:meth:`~.SkinnedBody.joint_transforms`):
        (B, J, 3, 3) rotations and (B, J, 3) translations."""
        rot = global_rotations @ self.rest_rotations.transpose(-1, -2)
        return rot, joint_positions - (rot * self.rest_positions[:, None, :]).sum(-1)

    def forward(
        self, points: torch.Tensor, global_rotations: torch.Tensor, joint_positions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(N,) signed distance (< 0 inside) and (N, 3) unit outward normal of points (N, 3) against
        the body posed by (J, 3, 3) global rotations and (J, 3) joint positions; or (B, N) and
        (B, N, 3) for (B, N, 3), (B, J, 3, 3), (B, J, 3)."""
        if points.dim() == 2:
            distance, normal = self.forward(points[None], global_rotations[None], joint_positions[None])
            return distance[0], normal[0]
        return self.query_moves(points, *self.moves(global_rotations, joint_positions))

    def query_moves(
        self, points: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """:meth:`forward` for the joints' moves (B, J, 3, 3) and (B, J, 3) (:meth:`moves`)."""
        b, n = points.shape[:2]
        character = torch.arange(b, device=points.device)[:, None].expand(b, n).reshape(-1)
        distance, normal = self.query_rows(points.reshape(-1, 3), character, rot, trans)
        return distance.reshape(b, n), normal.reshape(b, n, 3)

    def query_rows(
        self,
        points: torch.Tensor,
        character: torch.Tensor,
        rot: torch.Tensor,
        trans: torch.Tensor,
        *,
        surface: tuple = (),
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(K,) signed distance and (K, 3) outward normal of points (K, 3), each against its own
        ``character`` (K,) of the B whose joints moved by (B, J, 3, 3) and (B, J, 3): a crowd's
        points in one list, so that a push measures only the points it asks about, each
        character's mesh posed once (``surface``: the tensors of :meth:`surface` of these moves, where
        the caller measures them again; none: made here)."""
        surface = PosedSurface(*surface) if surface else self.surface(rot, trans)
        # a bound the exporter can see on a list of points made inside a graph's conditional (the
        # points a push's round moved): without one, its starts' count (3 x the largest int64)
        # overflows the int64 checks it writes into the graph
        torch._check(points.shape[0] <= MAX_POINTS)
        x = points.detach().t()[:, :, None]  # (3, K, 1): component-major
        rest, depth, under = self.rest_points(x, character, rot.detach(), trans.detach())
        node = self._node(rest)  # (K, S)
        # starts that settled on one node list the same faces and get the same answer: each
        # point's distinct nodes measured once (about half its starts on a body), the others copied
        starts = node.shape[1]
        first = _first_alike(node)  # (K, S): the first start on each start's node
        pairs = torch.nonzero((first == torch.arange(starts, device=node.device)).reshape(-1))[:, 0]
        point = torch.div(pairs, starts, rounding_mode="floor")
        d, n = self._nearest_face(
            torch.index_select(points, 0, point),
            torch.index_select(character, 0, point),
            torch.index_select(node.reshape(-1), 0, pairs),
            surface,
        )
        distance = torch.zeros_like(node, dtype=points.dtype).reshape(-1).index_copy(0, pairs, d)
        distance = torch.gather(distance.reshape(node.shape), 1, first)
        # (a zero of each (point, start) pair, in any order: every pair read is written first)
        normal = torch.zeros_like(points).repeat(starts, 1).index_copy(0, pairs, n)
        normal = torch.gather(normal.reshape(*node.shape, 3), 1, first[..., None].expand(*first.shape, 3))
        # the deepest settled start whose own nearest face puts the point inside too
        own_deep = torch.where(distance < 0.0, depth, torch.zeros_like(depth)).amax(-1)
        best = torch.argmin(distance.abs(), dim=-1, keepdim=True)
        distance = torch.gather(distance, -1, best)[..., 0]
        normal = torch.gather(normal, -2, best[..., None].expand(*best.shape, 3))[..., 0, :]
        return side_rules(distance, normal, own_deep=own_deep, under=under, settings=self.settings)

    def pose(self, rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor:
        """(B, V, 3) the mesh posed by the joints' moves (B, J, 3, 3) and (B, J, 3): linear blend
        skinning."""
        blend = (self.skin @ rot.flatten(-2)).unflatten(-1, (3, 3))  # (B, V, 3, 3): linear, not rigid
        return (blend * self.rest[:, None, :]).sum(-1) + self.skin @ trans

    def surface(self, rot: torch.Tensor, trans: torch.Tensor) -> "PosedSurface":
        """The mesh posed for each of B characters (:meth:`pose`) with what every point's nearest
        face reads of it, computed once a character rather than once a point and face."""
        posed = self.pose(rot, trans)
        fixed = posed.detach()
        tri = fixed[:, self.faces]  # (B, F, 3 corners, 3)
        a, ab, ac = tri[..., 0, :], tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :]
        dots = [
            (ab * ab).sum(-1, keepdim=True),
            (ab * ac).sum(-1, keepdim=True),
            (ac * ac).sum(-1, keepdim=True),
        ]
        # (12, B F): a, ab, ac and their products, one row each, so that a gather of faces gives planes
        planes = torch.cat([a, ab, ac, *dots], -1).reshape(-1, 12).t().contiguous()
        face_normals, vertex_normals = pseudo_normals(fixed, self.faces)
        return PosedSurface(posed, planes, face_normals.reshape(-1, 3), vertex_normals.reshape(-1, 3))

    def rest_points(
        self, x: torch.Tensor, character: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Inverse skinning of points, component-major (3, K, 1), each of its ``character`` (K,):
        (3, K, S) each start's rest point, (K, S) how deep inside the rest mesh each settled (0
        where it did not) and (K,) the depth of the deepest one, settled or not
        (:meth:`~hrr_garment.body.skin_collider.SkinCollider.rest_points`). Each point's joint
        moves are gathered from its character's: the products run on planes, not on last axes of 3."""
        b, joints = rot.shape[:2]
        # R_j^T (x - t_j) for every joint j at once: x's row times (3, 3 J), less R_j^T t_j
        spread = rot.permute(0, 2, 1, 3).reshape(b, 3, 3 * joints)
        offset = (trans[..., None] * rot).sum(-2).reshape(b, 3 * joints)
        px = x[:, :, 0].t()[:, None]  # (K, 1, 3)
        rigid = torch.bmm(px, torch.index_select(spread, 0, character))[:, 0]
        rigid = (rigid - torch.index_select(offset, 0, character)).reshape(-1, joints, 3)  # (K, J, 3)
        joint = torch.arange(joints, device=x.device)
        # a joint's own weight and the rest distance at the node its guess lands on: one table entry each
        at = self._node(rigid.permute(2, 0, 1)) * (joints + 1)  # (K, J)
        own, distance = self._entries(at + joint), self._entries(at + joints)
        rank = distance.abs() + (1.0 - own) * self.settings.off_skin_m
        # the starts in the stable order's first places: the lowest rank, ties to the lower joint
        # (argmin's first), then that joint out of the running
        chosen = []
        for _ in range(self.starts):
            pick = torch.argmin(rank, dim=-1, keepdim=True)
            chosen.append(pick)
            rank = torch.where(joint == pick, torch.full_like(rank, float("inf")), rank)
        chosen = torch.cat(chosen, -1)  # (K, S)
        rest = torch.gather(rigid, 1, chosen[..., None].expand(*chosen.shape, 3)).permute(2, 0, 1)
        moves = torch.index_select(torch.cat([rot.flatten(-2), trans], -1), 0, character)  # (K, J, 12)

        def fixed_point_step(k, rest):
            m, miss = self._miss(x, rest, moves)[1:]
            return k + 1, rest + self.settings.step * _solve3(m, miss)

        # the steps as a loop: an exported graph holds one step's operations, not each step's (unrolled,
        # nearly a third of the operators of a step's graph on a character's mesh)
        start = torch.zeros((), dtype=torch.int64, device=x.device)
        rest = exportable_while(
            lambda k, rest: k < self.settings.iterations, fixed_point_step, (start, rest)
        )[1]
        d, _, miss = self._miss(x, rest, moves)
        settled = (
            torch.sqrt(miss[0] * miss[0] + miss[1] * miss[1] + miss[2] * miss[2]) < self.settings.settled_m
        )
        below = torch.clamp(-d, min=0.0)
        return rest, torch.where(settled, below, torch.zeros_like(below)), below.amax(-1)

    def _miss(self, x: torch.Tensor, rest: torch.Tensor, moves: torch.Tensor) -> tuple:
        """At rest points (3, K, S) of points ``x`` (3, K, 1) with their joints' ``moves`` (K, J, 12):
        the rest distance (K, S), the blended move M(w) row by row then t(w) (12, K, S), and the
        three components of x - (M(w) rest + t(w)), each (K, S)."""
        w, d = self._read(rest)  # (K, S, J), (K, S)
        m = torch.bmm(w, moves).permute(2, 0, 1)
        miss = [
            x[i] - (m[3 * i] * rest[0] + m[3 * i + 1] * rest[1] + m[3 * i + 2] * rest[2]) - m[9 + i]
            for i in range(3)
        ]
        return d, m, miss

    def _entries(self, index: torch.Tensor) -> torch.Tensor:
        return torch.index_select(self.table.reshape(-1), 0, index.reshape(-1)).reshape(index.shape)

    def _node(self, rest: torch.Tensor) -> torch.Tensor:
        """The nearest node of rest points, component-major (3, ...), clamped to the grid."""
        g = [
            torch.minimum(
                torch.clamp(torch.round((rest[i] - self.origin[i]) / self.settings.voxel_m), min=0.0),
                self.top[i],
            )
            for i in range(3)
        ]
        return self._index(*(c.long() for c in g))

    def _index(self, g0: torch.Tensor, g1: torch.Tensor, g2: torch.Tensor) -> torch.Tensor:
        return (g0 * self.shape[1] + g1) * self.shape[2] + g2

    def _read(self, rest: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., J) skin weights and (...,) rest distance at rest points, component-major (3, ...),
        trilinear over the eight nodes about each (the reference's ``_read``: one gather of the
        eight rows, summed by their shares)."""
        g = [
            torch.minimum(
                torch.clamp((rest[i] - self.origin[i]) / self.settings.voxel_m, min=0.0), self.top[i]
            )
            for i in range(3)
        ]
        base = [torch.minimum(torch.floor(g[i]), torch.clamp(self.top[i] - 1.0, min=0.0)) for i in range(3)]
        # the eight corners' shares, corner c = 4 c0 + 2 c1 + c2 as ``corners`` orders them
        s0, s1, s2 = (torch.stack([1.0 - (g[i] - base[i]), g[i] - base[i]], -1) for i in range(3))
        share = (s0[..., :, None, None] * s1[..., None, :, None] * s2[..., None, None, :]).flatten(-3)
        node = self._index(*(c.long() for c in base))[..., None] + self.corner_offsets  # (..., 8)
        if torch.compiler.is_compiling():  # exporting: ONNX holds embedding_bag only as a Loop over the bags
            rows = torch.index_select(self.table, 0, node.reshape(-1)).reshape(*node.shape, self.joints + 1)
            out = (share[..., None] * rows).sum(-2)
        else:  # running: the gather and the weighted sum in one pass, several times faster on a CPU
            out = nn.functional.embedding_bag(
                node.reshape(-1, 8), self.table, per_sample_weights=share.reshape(-1, 8), mode="sum"
            ).reshape(*node.shape[:-1], self.joints + 1)
        return out[..., :-1], out[..., -1]

    def _nearest_face(
        self, points: torch.Tensor, character: torch.Tensor, node: torch.Tensor, surface: "PosedSurface"
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(P,) signed distance and (P, 3) outward normal of points (P, 3) to the nearest of the
        faces their nodes (P,) list, of each point's ``character``'s posed mesh (the reference's
        ``_nearest_face``). Every listed face is ranked by its distance from the face's planes
        (:meth:`surface`; no gradient), then the nearest one's point found again from its posed
        corners, as the reference finds it: that one carries the gradient."""
        count = len(self.faces)
        listed = torch.index_select(self.face_table, 0, node).long()  # (P, L)
        flat = (listed + (character * count)[:, None]).reshape(-1)
        near = torch.index_select(surface.planes, 1, flat).reshape(12, *listed.shape)  # (12, P, L)
        ap = points.detach().t()[:, :, None] - near[0:3]  # (3, P, L)
        ab, ac = near[3:6], near[6:9]
        v, w = closest_in_plane(dot(ab, ap), dot(ac, ap), aa=near[9], bc=near[10], cc=near[11])
        gap = ap - v * ab - w * ac
        best = torch.argmin(dot(gap, gap), dim=-1, keepdim=True)  # (P, 1)
        face = torch.gather(listed, -1, best)[:, 0]  # (P,)
        corners = torch.index_select(self.faces, 0, face)  # (P, 3)
        at, everyone = character * surface.posed.shape[1], surface.posed.reshape(-1, 3)
        # a corner at a time: reshaping a gather of a data-dependent length fails the exporter's first
        # trace (which prints the graph and traces again)
        tri = torch.stack([torch.index_select(everyone, 0, corners[:, c] + at) for c in range(3)])
        tri = tri.permute(0, 2, 1)  # (3 corners, 3, P)
        x = points.t()  # (3, P)
        bary = closest_on_triangles(x, tri)
        gap = x - (bary[0] * tri[0] + bary[1] * tri[1] + bary[2] * tri[2])  # (3, P)
        # kept off zero, where the square root's gradient is not finite
        length = torch.sqrt(torch.clamp(dot(gap, gap), min=1e-30))
        outward = self._pseudo_normal(surface, character, face, bary)
        gap = gap.t()  # (P, 3)
        inside = (gap * outward).sum(-1) < 0.0
        distance = torch.where(inside, -length, length)
        clear = (length > 1e-9)[:, None]
        normal = torch.where(clear, gap / torch.clamp(length, min=1e-12)[:, None], outward)
        normal = torch.where(inside[:, None] & clear, -normal, normal)
        return distance, normal / torch.clamp(
            torch.linalg.vector_norm(normal, dim=-1, keepdim=True), min=1e-12
        )

    def _pseudo_normal(
        self, surface: "PosedSurface", character: torch.Tensor, face: torch.Tensor, bary: torch.Tensor
    ) -> torch.Tensor:
        """(P, 3) the pseudonormal (:mod:`~hrr_garment.body.pseudo_normals`) at the nearest points
        on faces (P,) of their ``character``'s posed meshes at barycentric ``bary`` (3, P): the
        face's unit normal, the two faces' across an edge, a corner's angle-weighted normal. It only
        chooses the side (and the normal of a point on the skin), so it takes no gradient."""
        count, vertices = len(self.faces), surface.posed.shape[1]

        def pick(table: torch.Tensor, index: torch.Tensor, size: int) -> torch.Tensor:
            """(P, 3) rows ``index`` (P,) of each point's character's ``table`` (B size, 3)."""
            return torch.index_select(table, 0, index + character * size)

        z0, z1, z2 = bary[0] == 0.0, bary[1] == 0.0, bary[2] == 0.0
        zeros = z0.long() + z1.long() + z2.long()
        # on an edge, the one opposite the corner of no weight: from corner k + 1 to k + 2
        edge = torch.where(z0, 1, torch.where(z1, 2, 0))
        across = torch.gather(torch.index_select(self.neighbours, 0, face), -1, edge[:, None])[:, 0]
        own = pick(surface.face_normals, face, count)
        out = torch.where((zeros == 1)[:, None], own + pick(surface.face_normals, across, count), own)
        weighted = torch.where(~z0, 0, torch.where(~z1, 1, 2))  # on a corner: the one of weight 1
        corner = torch.gather(torch.index_select(self.faces, 0, face), -1, weighted[:, None])[:, 0]
        return torch.where((zeros == 2)[:, None], pick(surface.vertex_normals, corner, vertices), out)


class PosedSurface(NamedTuple):
    """What a query reads of the B characters' posed meshes (:meth:`SkinColliderGraph.surface`): a
    tuple of tensors, so that a graph's conditionals and loops carry it."""

    posed: torch.Tensor  # (B, V, 3) the meshes, with their gradient
    planes: torch.Tensor  # (12, B F) each face's corner a, edges ab and ac, ab.ab, ab.ac and ac.ac
    face_normals: torch.Tensor  # (B F, 3) unit
    vertex_normals: torch.Tensor  # (B V, 3) angle-weighted, unit


def _first_alike(node: torch.Tensor) -> torch.Tensor:
    """(K, S) for each start the first start of its point on the same node (itself where none)."""
    starts = node.shape[1]
    columns = []
    for s in range(starts):
        first = torch.full_like(node[:, s], s)
        for earlier in reversed(range(s)):  # the lowest written last
            first = torch.where(node[:, earlier] == node[:, s], earlier, first)
        columns.append(first)
    return torch.stack(columns, -1)


def _solve3(m: torch.Tensor, b: list) -> torch.Tensor:
    """M^-1 b for M's rows m[0:3], m[3:6], m[6:9] and b's components, all planes (...), by the
    adjugate, whose rows' cofactors are the cross products of the other two rows (skin_sdf.c's
    solve3: a blend of rotations is far from singular where skin is): (3, ...)."""
    r0, r1, r2 = m[0:3], m[3:6], m[6:9]
    c0, c1, c2 = cross(r1, r2, 0), cross(r2, r0, 0), cross(r0, r1, 0)
    inverse = 1.0 / dot(r0, c0)
    return (c0 * b[0] + c1 * b[1] + c2 * b[2]) * inverse
