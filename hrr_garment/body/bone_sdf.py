"""A collider that follows the body the viewer sees: the skinned mesh's signed distance, as a grid in
each joint's rest frame.

    collider = bone_sdf_collider(visible)                  # a SkinnedBody (:mod:`.skinned_body`)
    distance, normal = collider.query(points, motion.global_rotations[t], motion.joint_positions[t])

Built once a body, from its rest mesh: each joint's grid covers the box of its share of the skin (the
vertices it moves by at least :attr:`BoneSDFSettings.min_weight`, padded) in its rest frame, and holds
at each node the rest mesh's signed distance (signed by the mesh's normal at the nearest point), its
gradient, and the joint's skin weight at that nearest point. A posed point is taken into every
joint's frame (``R_j^T (x - p_j)``: the motion's own rotations and positions, the rest frame baked
into the grid) and each grid is read trilinearly. The joints that carry the nearest skin they see
answer, averaged by that skin weight and faded by how much farther their skin lies than the nearest
answer's (:attr:`BoneSDFSettings.blend_m`): along a bone its own grid answers alone; at a joint the
neighbours' answers mix as linear blend skinning mixes their vertices. The normal is the same average
of the grids' gradients, turned into the world.

How near it is meant to be (``tools/studies/visible_collider_study.py`` measures it on anny bodies
and real motion; ``tests/body/test_bone_sdf.py`` on a limb bent 90 degrees):

- at the rest pose, the exact signed distance within the grid's trilinear error: under a millimetre
  on a smooth limb, a few at a sharp rim, a millimetre on average on anny's coarse mesh;
- posed, within a few millimetres of the exact distance to the skinned mesh along the bones (p95
  4.3 mm on anny bodies in bent poses);
- where the skin is blended across joints (most of anny's), not: a p95 of 2.5 cm, up to 8 cm.
  Outside a bend skinning pulls the skin in past every joint's rigid grid, and deep in the fold of
  a bend the grid of the limb bent away can outvote the one the point is in (on a limb bent 90
  degrees, a point two centimetres inside can read as outside). :mod:`.skin_collider` supersedes
  these grids there (inverse skinning into one rest grid, measured against the posed faces: exact
  but for well under 1 % of points); they stay as the study's baseline. docs/bodies.md has the
  numbers and what was tried.

Points more than :attr:`BoneSDFSettings.padding_m` from the skin are only known to be at least that
far (their distance grows from the grid's edge).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh_distance import nearest_on_mesh, vertex_normals
from .skinned_body import SkinnedBody

CHANNELS = 5  # per node: signed distance, its gradient (x, y, z in the joint's frame), skin weight
NEAREST_CANDIDATES = 16  # faces tried per node (by centroid): a body's faces are of like size
# how far a joint's answer is set back where it carries none of the nearest skin: far enough that a
# joint carrying it wins, near enough that a point no grid claims takes the nearest grid's answer
# (anny bodies in bent poses: 1 m gave an error p99 of 37 mm and a max of 0.7 m; 0.1 m 32 mm, 74 mm)
OFF_SKIN_M = 0.1


@dataclass(frozen=True)
class BoneSDFSettings:
    """How the grids are built and blended."""

    # node spacing: trilinear error on a limb of radius r is about voxel^2 / (8 r), 0.4 mm at 1 cm
    # on a 3 cm wrist; the grids of an anny body are then about 0.5 M nodes (10 MB as float32)
    voxel_m: float = 0.01
    # how far past its share of the skin a joint's grid reaches: the band in which distances are
    # exact; past it, they grow from the grid's edge (a cloth vertex that far out needs no push)
    padding_m: float = 0.05
    # a vertex belongs to a joint's share from this skin weight: lower takes in more of the
    # neighbours' skin (wider overlap at joints, larger grids)
    min_weight: float = 0.05
    # a joint answers for a point where its skin weight at the nearest skin is at least the
    # second value, not at all under the first (a ramp between keeps the distance continuous)
    owner_weight: tuple[float, float] = (0.05, 0.2)
    # the joints that answer are averaged by skin weight, each faded by exp(-(|d| - min |d|) / blend_m):
    # where they agree (the blended skin at a joint) as skinning averages the skin; where one finds
    # the skin nearer (a limb bent across another) it wins. A signed soft minimum (the union) was
    # tried: it goes deeper than the skin where skinning pulls the skin in (on the average anny body
    # in bent poses, p95 error 31 mm against 18 mm, outside called inside 16 % against 10 %)
    blend_m: float = 0.01


@dataclass(frozen=True)
class BoneSDFCollider:
    """Every joint's grid, packed into one array (see the module docstring)."""

    joints: np.ndarray  # (B,) the joints with a share of the skin
    origin: np.ndarray  # (B, 3) each grid's first node in its joint's rest frame
    shape: np.ndarray  # (B, 3) int64 nodes along each axis
    start: np.ndarray  # (B,) int64 each grid's first row in ``values``
    values: np.ndarray  # (total nodes, CHANNELS) every grid's nodes, x-major
    settings: BoneSDFSettings

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
        rot = np.asarray(global_rotations, np.float64)[self.joints]  # (B, 3, 3)
        local = np.einsum("bji,nbj->nbi", rot, points[:, None] - np.asarray(joint_positions)[self.joints])
        sample, beyond = self._sample(local)  # (N, B, CHANNELS), (N, B)
        distance, weight = sample[..., 0] + beyond, np.clip(sample[..., 4], 0.0, 1.0)
        # a joint answers for a point where it carries the skin nearest to where it puts the point;
        # the others (their grids see other parts where those stood at rest) are set back by
        # OFF_SKIN_M, fading in over a ramp of skin weight so that the field stays continuous
        low, high = self.settings.owner_weight
        rank = np.abs(distance) + (1.0 - np.clip((weight - low) / (high - low), 0.0, 1.0)) * OFF_SKIN_M
        blend = (weight + 1e-6) * np.exp(-(rank - rank.min(1, keepdims=True)) / self.settings.blend_m)
        blend /= blend.sum(1, keepdims=True)
        normal = np.einsum("nb,bij,nbj->ni", blend, rot, sample[..., 1:4])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        return (blend * distance).sum(1), normal

    def _sample(self, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each grid read trilinearly at (N, B, 3) points in its frame, clamped to the grid, and how
        far each point lies outside its grid's box."""
        voxel = self.settings.voxel_m
        top = (self.shape - 1).astype(np.float64)
        g = (local - self.origin) / voxel
        inside = np.clip(g, 0.0, top)
        beyond = np.linalg.norm(g - inside, axis=-1) * voxel
        base = np.minimum(np.floor(inside), np.maximum(top - 1.0, 0.0)).astype(np.int64)
        frac = inside - base
        stride = np.stack(
            [self.shape[:, 1] * self.shape[:, 2], self.shape[:, 2], np.ones_like(self.start)], 1
        )
        row = self.start + (base * stride).sum(-1)  # (N, B)
        out = np.zeros((*local.shape[:2], CHANNELS))
        for corner in range(8):
            bit = np.array([(corner >> 2) & 1, (corner >> 1) & 1, corner & 1])
            weight = np.prod(np.where(bit, frac, 1.0 - frac), axis=-1)
            step = np.minimum(bit, self.shape - 1)  # a grid one node thick along an axis stays put
            out += weight[..., None] * self.values[row + (step * stride).sum(-1)]
        return out, beyond


def bone_sdf_collider(body: SkinnedBody, settings: BoneSDFSettings | None = None) -> BoneSDFCollider:
    """The grids of ``body``'s joints (a few seconds for an anny body on one core)."""
    settings = settings or BoneSDFSettings()
    normals = vertex_normals(body.vertices, body.faces)
    joints, origins, shapes, starts, grids, total = [], [], [], [], [], 0
    for j in range(body.weights.shape[1]):
        share = body.weights[:, j] >= settings.min_weight
        faces = body.faces[share[body.faces].any(1)]
        if not len(faces):
            continue
        rot, pos = body.rest_rotations[j], body.rest_positions[j]
        local = (body.vertices[np.unique(faces)] - pos) @ rot
        lo, hi = local.min(0) - settings.padding_m, local.max(0) + settings.padding_m
        shape = np.ceil((hi - lo) / settings.voxel_m).astype(np.int64) + 1
        axes = [lo[a] + settings.voxel_m * np.arange(shape[a]) for a in range(3)]
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        grid = _grid_values(nodes @ rot.T + pos, (body, normals), j, shape, settings.voxel_m)
        joints.append(j), origins.append(lo), shapes.append(shape), starts.append(total), grids.append(grid)
        total += len(grid)
    if not joints:
        raise ValueError("a skinned body with no faces has no collider")
    return BoneSDFCollider(
        np.array(joints),
        np.array(origins),
        np.array(shapes),
        np.array(starts),
        np.concatenate(grids),
        settings,
    )


def _grid_values(world: np.ndarray, mesh: tuple, joint: int, shape: np.ndarray, voxel: float) -> np.ndarray:
    """(nodes, CHANNELS) of one joint's grid at its nodes' rest positions ``world`` (x-major): the
    whole rest mesh's signed distance (by its normal at the nearest point) and the joint's weight
    there."""
    body, normals = mesh
    distance, face, bary = nearest_on_mesh(world, body.vertices, body.faces, candidates=NEAREST_CANDIDATES)
    corners = body.faces[face]  # (n, 3)
    closest = np.einsum("nk,nkc->nc", bary, body.vertices[corners])
    outward = np.einsum("nk,nkc->nc", bary, normals[corners])
    signed = np.where(((world - closest) * outward).sum(1) < 0.0, -distance, distance)
    cube = signed.reshape(shape)
    # the gradient in the joint's rest frame (the grid's axes), one-sided at the grid's faces
    gradient = np.stack(
        [np.gradient(cube, voxel, axis=a) if shape[a] > 1 else np.zeros_like(cube) for a in range(3)], -1
    )
    weight = (bary * body.weights[corners, joint]).sum(1)
    return np.concatenate([signed[:, None], gradient.reshape(-1, 3), weight[:, None]], 1)
