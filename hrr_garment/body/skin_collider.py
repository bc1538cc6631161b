"""A collider that is the body the viewer sees: the signed distance to the linear-blend-skinned mesh
in any pose, found through one grid of the rest pose by inverse skinning.

    collider = skin_collider(visible)                     # a SkinnedBody (:mod:`.skinned_body`)
    distance, normal = collider.query(points, motion.global_rotations[t], motion.joint_positions[t])

Built once a body, from its rest mesh: a grid over the rest mesh's box (2 cm nodes, padded) holds at
each node the rest mesh's signed distance, the skin weights of the nearest skin (its four largest)
and the faces that can be nearest to a point near the node (every face within the node's own
distance plus the cell's diameter and a slack, at most 16). A posed point ``x`` is taken back to
the rest pose by the blend of its joints' moves, ``r = M(w)^-1 x`` with ``M(w) = sum_j w_j T_j``
(``T_j`` the joint's move from the rest pose, :meth:`~.skinned_body.SkinnedBody.joint_transforms`)
and ``w`` the grid's skin weights at ``r``: a fixed point (SNARF's root finding, by damped
fixed-point steps), iterated from the rigid guesses ``T_j^-1 x`` of the three joints that land
nearest to skin of their own. On the skin the weights converge to the skin's own and ``r`` is the
rest point skinning carries onto ``x``.

The distance is then not read from the grid but measured: the faces the grid lists at each ``r``
are posed (their vertices skinned as a game skins them, flat triangles between) and the distance is
the exact distance to the nearest of them, inside where the pseudonormal of that nearest point's
face, edge or vertex says so (:mod:`.pseudo_normals`; within 5 cm of it, or of a start's rest
depth), or where a fixed point settled deep inside the rest mesh, its own nearest face agrees and
the nearest face lies no farther than that depth (the posed mesh overlapping itself). So wherever
a list holds the face that is nearest in the pose, the answer is the exact signed distance to the
mesh the viewer sees, joints and blended skin included; where none does, it is the distance to a
face of that mesh a little farther away (never nearer than the skin).

How near it is (``tools/studies/visible_collider_study.py`` on two anny bodies in the most bent
frames of real and procedural clips; ``tests/body/test_skin_collider.py`` on a limb bent 90
degrees; the numbers in docs/bodies.md):

- at rest, the exact signed distance within the grid's padding;
- on a limb bent 90 degrees, within 3 mm of the exact distance near the skin and on the right side
  of every point a centimetre or more inside or outside the bend;
- posed, the exact distance for 99 % of points near the skin, at joints and along bones alike (the
  error's p95 0.0 mm, its mean 0.2 mm at anny's blended joints); the rest are points where the
  fixed point settles off the skin (a root of the weights' extension off the skin, at the shoulders
  of a raised arm) or where the posed mesh overlaps itself: up to a few centimetres;
- the side: 1.0 % of the points more than 3 mm inside the posed mesh read as outside, 0.2 % of those
  outside as inside, at anny's blended joints (where the posed mesh overlaps itself, inside is the
  winding number's answer, which no nearest face gives; the deep rest point answers instead); of
  points anywhere about the body more than 3 cm from the skin, 0.00 % and 0.00 %.

The grid of an anny body: 150 to 170 thousand nodes, 13 to 15 MB (mostly the face lists), built in
about 6 s of one core's time. Points beyond :attr:`SkinColliderSettings.padding_m` of the rest skin get
the distance to faces near the grid's edge: at least as far as the nearest face, not exact. The
query is numpy (the reference); ``hrr_garment.native.skin`` is its C kernel.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .mesh_distance import closest_on_triangles
from .pseudo_normals import PseudoNormals, edge_neighbours, pseudo_normals
from .skinned_body import SkinnedBody

TOP_JOINTS = 4  # skin weights kept per node: the four largest (99 % of the weight on anny's skin)
SHORTLIST = 64  # faces tried per node when the grid is built (by centroid): a body's faces are of like size


@dataclass(frozen=True)
class SkinColliderSettings:
    """How the rest grid is built and read."""

    voxel_m: float = 0.02  # node spacing of the rest grid
    padding_m: float = 0.06  # how far past the rest mesh's box the grid reaches
    # a node lists every face within its own distance plus the cell's diameter (so that at rest the
    # nearest face of any point nearest to the node is listed) plus this slack (for the pose)
    slack_m: float = 0.005
    max_faces: int = 16  # the most faces a node lists, nearest first (32: no nearer on anny bodies)
    iterations: int = 4  # fixed-point steps of the inverse skinning
    # joints whose rigid guess starts a fixed point (on the average anny body in bent poses, the
    # error's p99 at joints: 2 starts 11 mm, 3 starts 2 mm, 4 starts 1 mm at a third more time)
    starts: int = 3
    # each fixed-point step goes this share of the way: undamped (1) it can swing between the two
    # sides of a shoulder and settle on a root off the skin (p99 error at joints 10 mm; 0.7: 2 mm)
    step: float = 0.7
    # a start whose rigid guess lands on another joint's skin counts as this much farther
    off_skin_m: float = 0.1
    # a fixed point has settled where it carries its rest point this near the posed one
    settled_m: float = 0.001
    # a settled rest point this far inside the rest mesh, whose own nearest face agrees, is inside,
    # whatever the nearest face says (chosen with the shading normals' side, on the average anny
    # body in bent poses, 3 mm: inside called outside 0.6 %, outside called inside 1.1 %; 10 mm:
    # 0.6 % and 0.5 %; 20 mm: 1.3 % and 0.35 %; never: 1.6 % and 0.15 %. With the pseudonormals'
    # side and its own face asked, on a heavy anny body in a dance: 0.86 % and 0.01 %; never: 2.1 %
    # and 0.01 %; without asking its own face: 0.70 % and 0.46 %)
    deep_m: float = 0.01
    # past this distance (plus a start's rest depth) the nearest face's normal no longer tells the
    # side (the face may be the nearest of the lists' but not of the mesh): points 3 to 50 cm from
    # the average anny body in bent poses, outside called inside 1.9 % without, 0.05 % with 5 cm;
    # inside called outside 0.1 %
    face_side_m: float = 0.05


@dataclass(frozen=True)
class SkinCollider:
    """The rest mesh with its skin and the rest grid (see the module docstring)."""

    body: SkinnedBody
    origin: np.ndarray  # (3,) the grid's first node in the rest pose
    shape: np.ndarray  # (3,) int64 nodes along each axis
    distance: np.ndarray  # (nodes,) float32 the rest mesh's signed distance, x-major
    joints: np.ndarray  # (nodes, TOP_JOINTS) uint8 the nearest skin's joints, largest weight first
    weights: np.ndarray  # (nodes, TOP_JOINTS) float32 their weights (summing to 1)
    face_start: np.ndarray  # (nodes + 1,) int32 each node's first entry in ``face_list``
    face_list: np.ndarray  # (entries,) int32 the faces each node lists
    settings: SkinColliderSettings

    @property
    def nbytes(self) -> int:
        """The grid's memory (the mesh aside)."""
        return (
            self.distance.nbytes
            + self.joints.nbytes
            + self.weights.nbytes
            + self.face_start.nbytes
            + self.face_list.nbytes
        )

    def query(
        self, points: np.ndarray, global_rotations: np.ndarray, joint_positions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(N,) signed distance (< 0 inside) and (N, 3) unit outward normal of world ``points``
        (N, 3) against the body posed by (J, 3, 3) global rotations and (J, 3) joint positions;
        (T, N, 3) points with (T, J, 3, 3) and (T, J, 3) give (T, N) and (T, N, 3)."""
        points = np.asarray(points, np.float64)
        if points.ndim == 3:
            out = [self.query(p, r, x) for p, r, x in zip(points, global_rotations, joint_positions)]
            return np.stack([d for d, _ in out]), np.stack([n for _, n in out])
        rot, trans = self.body.joint_transforms(global_rotations[None], joint_positions[None])
        rot, trans = rot[0], trans[0]
        posed = self.body.pose(global_rotations[None], joint_positions[None])[0]
        normals = pseudo_normals(posed, self.body.faces)
        answers, own_deep, under = [], np.zeros(len(points)), np.zeros(len(points))
        for rest, depth, below in self.rest_points(points, rot, trans):
            d, n = self._nearest_face(points, self._listed(self._node(rest)), posed, normals)
            answers.append((d, n))
            own_deep = np.maximum(own_deep, np.where(d < 0.0, depth, 0.0))
            under = np.maximum(under, below)
        best = np.argmin(np.stack([np.abs(d) for d, _ in answers]), 0)[None, :, None]
        distance = np.take_along_axis(np.stack([d for d, _ in answers])[..., None], best, 0)[0, :, 0]
        normal = np.take_along_axis(np.stack([n for _, n in answers]), best, 0)[0]
        return side_rules(distance, normal, own_deep=own_deep, under=under, settings=self.settings)

    def rest_points(
        self, points: np.ndarray, rot: np.ndarray, trans: np.ndarray
    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Where inverse skinning takes posed ``points`` (N, 3) in the rest pose, for the joints'
        moves ``rot`` (J, 3, 3) and ``trans`` (J, 3): for each start, (N, 3) rest points, (N,) how
        deep inside the rest mesh the fixed point settled (0 where it did not, or outside) and (N,)
        how deep inside the rest mesh its last rest point lies, settled or not."""
        rigid = np.einsum("jba,njb->nja", rot, points[:, None] - trans)  # (N, J, 3): T_j^-1 x
        node = self._node(rigid)  # (N, J)
        # the joints whose rigid guess lands nearest to skin of their own start: a guess landing on
        # another joint's skin (or far from any) counts as ``off_skin_m`` farther
        mine = self.joints[node] == np.arange(len(rot))[:, None]
        own = np.where(mine, self.weights[node].astype(np.float64), 0.0).sum(-1)
        rank = np.abs(self.distance[node].astype(np.float64)) + (1.0 - own) * self.settings.off_skin_m
        order = np.argsort(rank, axis=1, kind="stable")[:, : self.settings.starts]
        out = []
        for rest in np.moveaxis(np.take_along_axis(rigid, order[..., None], 1), 1, 0):
            for k in range(self.settings.iterations + 1):
                w, d = self._read(rest)  # (N, J), (N,)
                m = np.einsum("nj,jab->nab", w, rot)
                # x - M(w) r - t(w): how far the last step's rest point lands from x
                miss = points - np.einsum("nab,nb->na", m, rest) - w @ trans
                step = np.linalg.solve(m, miss[..., None])[..., 0]
                rest = rest + self.settings.step * step if k < self.settings.iterations else rest
            settled = np.linalg.norm(miss, axis=1) < self.settings.settled_m
            out.append((rest, np.where(settled, np.maximum(-d, 0.0), 0.0), np.maximum(-d, 0.0)))
        return out

    def _node(self, rest: np.ndarray) -> np.ndarray:
        """The nearest node's row of rest points (..., 3), clamped to the grid."""
        g = np.clip(np.rint((rest - self.origin) / self.settings.voxel_m), 0, self.shape - 1).astype(np.int64)
        return (g[..., 0] * self.shape[1] + g[..., 1]) * self.shape[2] + g[..., 2]

    def _listed(self, node: np.ndarray) -> np.ndarray:
        """(N, k) the faces nodes (N,) list, each row padded with its first."""
        start, count = self.face_start[node], np.diff(self.face_start)[node]
        col = np.minimum(np.arange(count.max()), count[:, None] - 1)
        return self.face_list[start[:, None] + col]

    def _read(self, rest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, J) the skin weights and (N,) the signed distance at rest points (N, 3), trilinear
        over the grid's eight nodes."""
        voxel, top = self.settings.voxel_m, (self.shape - 1).astype(np.float64)
        g = np.clip((rest - self.origin) / voxel, 0.0, top)
        base = np.minimum(np.floor(g), np.maximum(top - 1.0, 0.0)).astype(np.int64)
        frac = g - base
        out, distance = np.zeros((len(rest), len(self.body.rest_positions))), np.zeros(len(rest))
        rows = np.arange(len(rest))[:, None]
        for corner in range(8):
            bit = np.array([(corner >> 2) & 1, (corner >> 1) & 1, corner & 1])
            c = base + np.minimum(bit, self.shape - 1)
            node = (c[:, 0] * self.shape[1] + c[:, 1]) * self.shape[2] + c[:, 2]
            share = np.prod(np.where(bit, frac, 1.0 - frac), axis=-1)
            np.add.at(out, (rows, self.joints[node]), share[:, None] * self.weights[node])
            distance += share * self.distance[node]
        return out, distance

    def _nearest_face(
        self, points: np.ndarray, candidates: np.ndarray, posed: np.ndarray, normals: PseudoNormals
    ) -> tuple[np.ndarray, np.ndarray]:
        """The signed distance and outward normal of each point (N, 3) to the nearest of its
        candidate faces (N, k) of the ``posed`` mesh, the side by the pseudonormal of the nearest
        point's face, edge or vertex (``normals``, :mod:`.pseudo_normals`)."""
        n, k = candidates.shape
        tri = posed[self.body.faces[candidates.ravel()]]  # (N k, 3, 3)
        rep = np.repeat(points, k, axis=0)
        bary = closest_on_triangles(rep, tri)
        gap = rep - np.einsum("mk,mkc->mc", bary, tri)
        length = np.linalg.norm(gap, axis=1).reshape(n, k)
        best = length.argmin(1)
        rows = np.arange(n)
        pick = rows * k + best
        outward = normals.at(self.body.faces, candidates[rows, best], bary[pick], self.neighbours)
        inside = (gap[pick] * outward).sum(1) < 0.0
        distance = np.where(inside, -length[rows, best], length[rows, best])
        clear = length[rows, best] > 1e-9
        normal = np.where(clear[:, None], gap[pick] / np.maximum(length[rows, best], 1e-12)[:, None], outward)
        normal = np.where(inside[:, None] & clear[:, None], -normal, normal)
        return distance, normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)

    @cached_property
    def neighbours(self) -> np.ndarray:
        """(F, 3) the face across each face's edges (:func:`~.pseudo_normals.edge_neighbours`)."""
        return edge_neighbours(self.body.faces)


def side_rules(distance, normal, *, own_deep, under, settings: SkinColliderSettings):
    """The nearest face's signed ``distance`` and ``normal`` with the side settled by the depth rules:
    where the posed mesh overlaps itself (a thigh pressed into the other, an arm into the chest) the
    nearest face can be one buried in the other part, facing away, so a point is also inside where
    a start settled deep inside the rest mesh (``own_deep``: the deepest such start whose own nearest
    face also puts the point inside) and the nearest face is no farther than that depth (skinning
    carries some rest points inside the chest off with the arm, far from any skin: their own faces
    put them outside). The face's normal says inside within ``face_side_m`` of it, or of the depth
    ``under`` of a start's last rest point, settled or not. Numpy arrays (the reference) or torch
    tensors (:class:`~hrr_garment.models.skin_collider_graph.SkinColliderGraph`) alike: operators only."""
    deep, side = settings.deep_m, settings.face_side_m
    near_face = (distance >= -side) | ((under > deep) & (distance >= -(under + side)))
    inside = ((distance < 0.0) & near_face) | ((own_deep > deep) & (abs(distance) <= own_deep + deep))
    sign = 1.0 - 2.0 * (inside != (distance < 0.0))  # -1 where the rules flip the face's side
    return distance * sign, normal * sign[..., None]


def skin_collider(body: SkinnedBody, settings: SkinColliderSettings | None = None) -> SkinCollider:
    """The rest grid of ``body`` (a few seconds for an anny body on one core)."""
    settings = settings or SkinColliderSettings()
    if not len(body.faces):
        raise ValueError("a skinned body with no faces has no collider")
    if body.weights.shape[1] > 255:
        raise ValueError(
            f"the collider keeps joint indices in a byte: {body.weights.shape[1]} joints are too many"
        )
    lo = body.vertices.min(0) - settings.padding_m
    shape = np.ceil((body.vertices.max(0) + settings.padding_m - lo) / settings.voxel_m).astype(np.int64) + 1
    axes = [lo[a] + settings.voxel_m * np.arange(shape[a]) for a in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    reach = settings.voxel_m * np.sqrt(3.0) + settings.slack_m
    listed, bary = _faces_within(nodes, body, reach, settings.max_faces)
    first = np.array([f[0] for f in listed], np.int64)
    corners = body.faces[first]
    closest = np.einsum("nk,nkc->nc", bary, body.vertices[corners])
    normals = pseudo_normals(body.vertices, body.faces)
    outward = normals.at(body.faces, first, bary, edge_neighbours(body.faces))
    length = np.linalg.norm(nodes - closest, axis=1)
    signed = np.where(((nodes - closest) * outward).sum(1) < 0.0, -length, length)
    skin = np.einsum("nk,nkj->nj", bary, body.weights[corners])  # (nodes, J)
    skin = np.pad(skin, ((0, 0), (0, max(0, TOP_JOINTS - skin.shape[1]))))  # fewer joints: weight 0
    joints = np.argsort(-skin, axis=1, kind="stable")[:, :TOP_JOINTS]
    weights = np.take_along_axis(skin, joints, 1)
    joints = np.where(joints < body.weights.shape[1], joints, 0)  # the padding's, at weight 0
    return SkinCollider(
        body,
        lo,
        shape,
        signed.astype(np.float32),
        joints.astype(np.uint8),
        (weights / weights.sum(1, keepdims=True)).astype(np.float32),
        np.concatenate([[0], np.cumsum([len(f) for f in listed])]).astype(np.int32),
        np.concatenate(listed).astype(np.int32),
        settings,
    )


def _faces_within(nodes: np.ndarray, body: SkinnedBody, reach: float, most: int) -> tuple[list, np.ndarray]:
    """Each node's faces within ``reach`` of its nearest distance, nearest first (at most ``most``),
    and (nodes, 3) the barycentric coordinates of the nearest point on the first."""
    from scipy.spatial import cKDTree

    tri = body.vertices[body.faces]
    k = min(SHORTLIST, len(tri))
    shortlist = cKDTree(tri.mean(1)).query(nodes, k)[1].reshape(len(nodes), k)
    listed, bary = [], np.empty((len(nodes), 3))
    step = max(1, 250_000 // k)
    for s in range(0, len(nodes), step):
        cand = shortlist[s : s + step]
        p = np.repeat(nodes[s : s + step], k, axis=0)
        t = tri[cand.ravel()]
        b = closest_on_triangles(p, t)
        d = np.linalg.norm(p - np.einsum("mk,mkc->mc", b, t), axis=1).reshape(len(cand), k)
        order = np.argsort(d, axis=1)
        bary[s : s + step] = b.reshape(len(cand), k, 3)[np.arange(len(cand)), order[:, 0]]
        d, cand = np.take_along_axis(d, order, 1), np.take_along_axis(cand, order, 1)
        keep = d <= d[:, :1] + reach
        keep[:, most:] = False
        listed += [c[m] for c, m in zip(cand, keep)]
    return listed, bary
