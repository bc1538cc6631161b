"""The collider of the body the viewer sees (:class:`~hrr_garment.body.skin_collider.SkinCollider`,
the numpy reference; ``hrr_garment.native.skin`` its C kernel) as a torch module that ONNX can
hold and autograd can differentiate: the same starts, fixed-point steps, face lists and sign rules,
in gathers, batched products and ``where``, with shapes that depend on no point's answer.

    graph = SkinColliderGraph(skin_collider(visible))            # float32; dtype=torch.float64 too
    distance, normal = graph(points, global_rotations, joint_positions)   # (N,), (N, 3)

Batched over B characters as well: points (B, N, 3) with (B, J, 3, 3) and (B, J, 3).
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

import numpy as np
import torch
from torch import nn

from ..body.skin_collider import side_rules
from .torch_mesh import closest_on_triangles, cross, dot, pseudo_normals


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
        corners = [[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)]
        self.register_buffer("corners", torch.tensor(corners, dtype=torch.int64))

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
        posed = self.pose(rot, trans)
        rest, depth, under = self.rest_points(points.detach(), rot.detach(), trans.detach())
        distance, normal = self._nearest_face(points, self._node(rest), posed)  # (B, N, S)
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

    def rest_points(
        self, points: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Inverse skinning of points (B, N, 3): (B, N, S, 3) each start's rest point, (B, N, S) how
        deep inside the rest mesh each settled (0 where it did not) and (B, N) the depth of the
        deepest one, settled or not (:meth:`~hrr_garment.body.skin_collider.SkinCollider.rest_points`)."""
        rigid = torch.einsum("bnjc,bjca->bnja", points[:, :, None] - trans[:, None], rot)  # R^T (x - t)
        joint = torch.arange(self.joints, device=points.device)
        # a joint's own weight and the rest distance at the node its guess lands on: one table entry each
        at = self._node(rigid) * (self.joints + 1)  # (B, N, J)
        own, distance = self._entries(at + joint), self._entries(at + self.joints)
        rank = distance.abs() + (1.0 - own) * self.settings.off_skin_m
        # the starts in the stable order's first places: the lowest rank, ties to the lower joint
        # (argmin's first), then that joint out of the running
        chosen = []
        for _ in range(self.starts):
            pick = torch.argmin(rank, dim=-1, keepdim=True)
            chosen.append(pick)
            rank = torch.where(joint == pick, torch.full_like(rank, float("inf")), rank)
        chosen = torch.cat(chosen, -1)  # (B, N, S)
        rest = torch.gather(rigid, 2, chosen[..., None].expand(*chosen.shape, 3))
        x = points[:, :, None]
        moves = torch.cat([rot.flatten(-2), trans], -1)  # (B, J, 12)
        for k in range(self.settings.iterations + 1):
            w, d = self._read(rest)  # (B, N, S, J), (B, N, S)
            blend = (w.flatten(1, 2) @ moves).reshape(*rest.shape[:-1], 12)  # one product a character
            m = blend[..., :9].unflatten(-1, (3, 3))
            miss = x - (m * rest[..., None, :]).sum(-1) - blend[..., 9:]
            if k < self.settings.iterations:
                rest = rest + self.settings.step * _solve3(m, miss)
        settled = torch.linalg.vector_norm(miss, dim=-1) < self.settings.settled_m
        below = torch.clamp(-d, min=0.0)
        return rest, torch.where(settled, below, torch.zeros_like(below)), below.amax(-1)

    def _entries(self, index: torch.Tensor) -> torch.Tensor:
        return torch.index_select(self.table.reshape(-1), 0, index.reshape(-1)).reshape(index.shape)

    def _node(self, rest: torch.Tensor) -> torch.Tensor:
        """The nearest node of rest points (..., 3), clamped to the grid."""
        g = torch.round((rest - self.origin) / self.settings.voxel_m)
        return self._index(torch.minimum(torch.clamp(g, min=0.0), self.top).long())

    def _index(self, g: torch.Tensor) -> torch.Tensor:
        return (g[..., 0] * self.shape[1] + g[..., 1]) * self.shape[2] + g[..., 2]

    def _read(self, rest: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., J) skin weights and (...,) rest distance at rest points (..., 3), trilinear over the
        eight nodes about each (the reference's ``_read``: one gather of the eight rows, summed by
        a product)."""
        g = torch.minimum(torch.clamp((rest - self.origin) / self.settings.voxel_m, min=0.0), self.top)
        base = torch.minimum(torch.floor(g), torch.clamp(self.top - 1.0, min=0.0))
        frac = g[..., None, :] - base[..., None, :]  # (..., 1, 3)
        node = self._index(
            base[..., None, :].long() + torch.minimum(self.corners, self.shape - 1)
        )  # (..., 8)
        share = torch.where(self.corners > 0, frac, 1.0 - frac)
        share = share[..., 0] * share[..., 1] * share[..., 2]  # (..., 8)
        if torch.compiler.is_compiling():  # exporting: ONNX holds embedding_bag only as a Loop over the bags
            rows = torch.index_select(self.table, 0, node.reshape(-1)).reshape(*node.shape, self.joints + 1)
            out = (share[..., None] * rows).sum(-2)
        else:  # running: the gather and the weighted sum in one pass, several times faster on a CPU
            out = nn.functional.embedding_bag(
                node.reshape(-1, 8), self.table, per_sample_weights=share.reshape(-1, 8), mode="sum"
            ).reshape(*node.shape[:-1], self.joints + 1)
        return out[..., :-1], out[..., -1]

    def _nearest_face(
        self, points: torch.Tensor, node: torch.Tensor, posed: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, N, S) signed distance and (B, N, S, 3) outward normal of points (B, N, 3) to the
        nearest of the faces each start's node (B, N, S) lists, of the ``posed`` meshes (B, V, 3)
        (the reference's ``_nearest_face``), the triangles component-major (3, 3, B, N, S, K)."""
        b, v = posed.shape[:2]
        # the list's length by name, not -1: an ONNX Reshape cannot infer a -1 where no point is asked
        # (the projection loop's points inside, often none)
        listed = (
            torch.index_select(self.face_table, 0, node.reshape(-1))
            .reshape(*node.shape, self.face_table.shape[1])
            .long()
        )
        frames = torch.arange(b, device=posed.device).reshape(b, 1, 1, 1)
        everyone = posed[:, self.faces].reshape(-1, 9)  # (B F, 9): rows gather fastest
        flat = (listed + frames * len(self.faces)).reshape(-1)
        tri = torch.index_select(everyone, 0, flat).t().contiguous().reshape(3, 3, *listed.shape)
        x = points.permute(2, 0, 1)[..., None, None]  # (3, B, N, 1, 1)
        bary = closest_on_triangles(x, tri)
        gap = x - (bary[0] * tri[0] + bary[1] * tri[1] + bary[2] * tri[2])
        # (B, N, S, K); kept off zero, where the square root's gradient is not finite
        length = torch.sqrt(torch.clamp(dot(gap, gap), min=1e-30))
        best = torch.argmin(length, dim=-1, keepdim=True)
        length = torch.gather(length, -1, best)[..., 0]

        def pick(value: torch.Tensor) -> torch.Tensor:  # (3, B, N, S, K) -> (B, N, S, 3)
            return torch.gather(value, -1, best[None].expand(3, *best.shape))[..., 0].permute(1, 2, 3, 0)

        bary, gap = pick(bary), pick(gap)
        outward = self._pseudo_normal(posed.detach(), torch.gather(listed, -1, best)[..., 0], bary)
        inside = (gap * outward).sum(-1) < 0.0
        distance = torch.where(inside, -length, length)
        clear = (length > 1e-9)[..., None]
        normal = torch.where(clear, gap / torch.clamp(length, min=1e-12)[..., None], outward)
        normal = torch.where(inside[..., None] & clear, -normal, normal)
        return distance, normal / torch.clamp(
            torch.linalg.vector_norm(normal, dim=-1, keepdim=True), min=1e-12
        )

    def _pseudo_normal(self, posed: torch.Tensor, face: torch.Tensor, bary: torch.Tensor) -> torch.Tensor:
        """(B, N, S, 3) the pseudonormal (:mod:`~hrr_garment.body.pseudo_normals`) at the nearest
        points on faces (B, N, S) of the ``posed`` meshes (B, V, 3) at barycentric ``bary`` (B, N, S,
        3): the face's unit normal, the two faces' across an edge, a corner's angle-weighted normal.
        It only chooses the side (and the normal of a point on the skin), so it takes no gradient."""
        b, v = posed.shape[:2]
        face_normals, vertex = pseudo_normals(posed, self.faces)  # (B, F, 3), (B, V, 3)
        frames = torch.arange(b, device=posed.device).reshape(b, 1, 1)

        def rows(table: torch.Tensor, index: torch.Tensor, count: int) -> torch.Tensor:
            """(B, N, S, 3) rows ``index`` (B, N, S) of each frame's ``table`` (B, count, 3)."""
            flat = (index + frames * count).reshape(-1)
            return torch.index_select(table.reshape(-1, 3), 0, flat).reshape(*index.shape, 3)

        zero = bary == 0.0
        count = zero.sum(-1)
        # on an edge, the one opposite the corner of no weight: from corner k + 1 to k + 2
        edge = torch.remainder(torch.argmax(zero.to(torch.int64), -1) + 1, 3)
        across = torch.gather(self.neighbours[face], -1, edge[..., None])[..., 0]
        own = rows(face_normals, face, len(self.faces))
        out = torch.where((count == 1)[..., None], own + rows(face_normals, across, len(self.faces)), own)
        weighted = torch.argmax((~zero).to(torch.int64), -1)[..., None]
        corner = torch.gather(self.faces[face], -1, weighted)[..., 0]
        return torch.where((count == 2)[..., None], rows(vertex, corner, v), out)


def _solve3(m: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """m^-1 b for (..., 3, 3) and (..., 3) by the adjugate, whose rows' cofactors are the cross
    products of the other two rows (skin_sdf.c's solve3: a blend of rotations is far from singular
    where skin is)."""
    r0, r1, r2 = m.unbind(-2)
    c0, c1, c2 = cross(r1, r2), cross(r2, r0), cross(r0, r1)
    inverse = 1.0 / (r0 * c0).sum(-1, keepdim=True)
    return (c0 * b[..., :1] + c1 * b[..., 1:2] + c2 * b[..., 2:]) * inverse
