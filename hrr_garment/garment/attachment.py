"""Attached vertices follow the body by linear blend skinning to their nearest bones.

Each attached vertex is bound, in the rest pose, to the joints of its two nearest capsules (by
signed distance), weighted by inverse squared distance; a waistband vertex between the pelvis and
the spine thus blends both, a strap vertex on the shoulder follows the collar. Only torso joints
are candidates: a strap that took 12 % of the upper arm's rotation stretched by 65 % when the arm
dropped from the T-pose, and a waistband must not follow a swinging thigh.

On the body the viewer sees, each attached vertex rides the face of the skin nearest to it instead
(:class:`SkinFaceBinding`: where skinning puts that face, at the vertex's clearance along its
normal), and the skin stretches where linear blend skinning stretches it: over a shoulder, as
the arm comes down from the T-pose, by up to 33 %. A strap of cloth would slide over that skin
rather than stretch with it, so the posed attached vertices are relaxed: every edge between two of
them longer than at rest is drawn back towards its rest length, the two ends moving alike (never
pushed apart), as the strap sliding along the skin. And there a strap rides the skin whole
(:func:`riding_skin`): held at its top only, its free part was carried outwards by the skin under
it, which moves with the arms, and stretched (a dash's arm swing tore it on three of seven bodies).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, capsule_signed_distance
from ..body.mesh_distance import nearest_on_mesh
from ..body.skinned_body import SkinnedBody
from ..motion.skeleton import JOINT_INDEX, PARENTS
from .mesh import GarmentMesh

# Jacobi passes drawing stretched edges between attached vertices back (anny bodies, three Bandai
# clips: between attached vertices, strain p99 1.26-1.28 -> 1.10 after 10 passes, 1.04 after 30,
# 1.01 after 60, 1.004 after 100; the pins move 1 mm on average, 12.6 mm at most)
RELAX_PASSES = 60
TORSO_JOINTS: tuple[str, ...] = ("pelvis", "spine1", "spine2", "spine3", "neck", "l_collar", "r_collar")


@dataclass(frozen=True)
class SkinBinding:
    """vertices (A,) garment indices; joints (A, K); weights (A, K) summing to 1; offsets (A, K, 3)
    rest-pose position relative to each joint (the rest pose has identity global rotations)."""

    vertices: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    offsets: np.ndarray

    def pose(self, global_rotations: np.ndarray, joint_positions: np.ndarray) -> np.ndarray:
        """(T, A, 3) attached vertex positions for FK results (T, 22, 3, 3) and (T, 22, 3)."""
        rot = global_rotations[:, self.joints]  # (T, A, K, 3, 3)
        pos = joint_positions[:, self.joints]  # (T, A, K, 3)
        per_joint = np.einsum("takij,akj->taki", rot, self.offsets) + pos
        return np.einsum("taki,ak->tai", per_joint, self.weights)


def riding_skin(garment: GarmentMesh) -> GarmentMesh:
    """``garment`` as the body the viewer sees carries it: its straps (a template's ``straps``
    group, where it has one) attached whole, as skin-tight straps ride the shoulders; a garment
    without straps as it is. On seven bodies and six Bandai clips (docs/bodies.md), the dress kept
    all 42 clips this way where strap tops alone tore four."""
    if "straps" not in garment.groups or "straps" in garment.attached_groups:
        return garment
    return replace(garment, attached_groups=(*garment.attached_groups, "straps"))


def relax_stretch(
    positions: np.ndarray, edges: np.ndarray, rest_lengths: np.ndarray, passes: int = RELAX_PASSES
) -> np.ndarray:
    """(T, A, 3) ``positions`` with every edge longer than its rest length drawn back towards it:
    Jacobi passes, each end of a stretched edge moving half the excess along it (averaged over the
    vertex's edges), shorter edges left alone. A function of each frame alone, so smooth in time
    wherever the posed vertices are."""
    out = np.array(positions, np.float64)
    a, b = edges[:, 0], edges[:, 1]
    shares = np.bincount(edges.ravel(), minlength=out.shape[1]).astype(np.float64)
    shares = np.maximum(shares, 1.0)[None, :, None]
    for _ in range(passes):
        along = out[:, b] - out[:, a]  # (T, E, 3)
        length = np.linalg.norm(along, axis=-1)
        excess = np.maximum(length - rest_lengths, 0.0) / np.maximum(length, 1e-12)
        step = 0.5 * excess[..., None] * along
        moves = np.zeros_like(out)
        np.add.at(moves, (slice(None), a), step)
        np.add.at(moves, (slice(None), b), -step)
        out += moves / shares
    return out


def bind_attached(
    mesh: GarmentMesh, body: BodyModel = DEFAULT_BODY, bones: int = 2, joints: tuple[str, ...] = TORSO_JOINTS
) -> SkinBinding:
    """Skin the mesh's attached vertices (rest pose) to the nearest capsules among ``joints``."""
    verts = mesh.vertices[mesh.attached].astype(np.float64)
    joints_rest = body.rest_joints()  # the body's own rest joints (the mannequin's by default)
    a, b = body.rest_pose()
    cap_joint = np.array([JOINT_INDEX[c.joint] for c in body.capsules])
    # Distance to every capsule, then the nearest capsule per distinct joint.
    dist = np.stack(
        [
            capsule_signed_distance(verts, a[c : c + 1], b[c : c + 1], radii=body.radii[c : c + 1])[0]
            for c in range(len(cap_joint))
        ],
        1,
    )
    per_joint = np.full((len(verts), len(PARENTS)), np.inf)
    allowed = {JOINT_INDEX[name] for name in joints}
    for c, j in enumerate(cap_joint):
        if j in allowed:
            per_joint[:, j] = np.minimum(per_joint[:, j], dist[:, c])
    nearest = np.argsort(per_joint, axis=1)[:, :bones]
    d = np.take_along_axis(per_joint, nearest, axis=1)
    w = 1.0 / np.maximum(d - d[:, :1] + 0.01, 1e-3) ** 2  # relative to the nearest: 1 cm softening
    w /= w.sum(1, keepdims=True)
    offsets = verts[:, None, :] - joints_rest[nearest]
    return SkinBinding(mesh.attached.copy(), nearest.astype(np.int64), w.astype(np.float64), offsets)


@dataclass(frozen=True)
class SkinFaceBinding:
    """Attached vertices (``vertices`` (A,) garment indices) that ride the skin's surface: each at
    its face's point (``bary`` of ``skin``'s face of the same row: ``skin`` holds only the skin's
    faces the attached vertices ride, one a vertex, and the vertices those use) plus its rest offset
    from it in the face's own frame (``local``: along the face's two edges from its first corner and
    its unit normal), as the face is posed by linear blend skinning; then every edge of ``held``
    (E, 2, indices into ``vertices``) longer than its rest length (``held_lengths``) relaxed
    (:func:`relax_stretch`). Bound to the joints' blend instead, a pin sinks into the skin where
    skinning bulges it (a dress with its straps attached whole had 1.2 % of its vertices inside the
    mesh); on its face it keeps its clearance."""

    vertices: np.ndarray
    skin: SkinnedBody
    bary: np.ndarray
    local: np.ndarray
    held: np.ndarray
    held_lengths: np.ndarray

    @property
    def offset(self) -> np.ndarray:
        """(A,) each attached vertex's rest distance from its face's plane."""
        return self.local[:, 2]

    def pose(self, global_rotations: np.ndarray, joint_positions: np.ndarray) -> np.ndarray:
        """(T, A, 3) attached vertex positions for FK results (T, J, 3, 3) and (T, J, 3)."""
        corners = self.skin.pose(global_rotations, joint_positions)[:, self.skin.faces]  # (T, A, 3, 3)
        point = np.einsum("takc,ak->tac", corners, self.bary)
        frame = _face_frames(corners)  # (T, A, 3, 3): two edges and the unit normal
        riding = point + np.einsum("takc,ak->tac", frame, self.local)
        return relax_stretch(riding, self.held, self.held_lengths) if len(self.held) else riding


def bind_attached_to_skin(mesh: GarmentMesh, skin: SkinnedBody, body: BodyModel) -> SkinFaceBinding:
    """Bind the mesh's attached vertices (rest pose) to the faces of ``skin`` nearest to each in
    ``body``'s rest pose, at their distance along each face's normal, so that a strap or a waistband
    rides the body the viewer sees (a strap bound to the torso's capsules alone sank into the
    shoulder's skin, which follows the arm)."""
    from .visible_surface import rest_mesh

    verts = mesh.vertices[mesh.attached].astype(np.float64)
    at_rest = rest_mesh(skin, body)
    _, face, bary = nearest_on_mesh(verts, at_rest, skin.faces)
    corners = at_rest[skin.faces[face]]
    frame = _face_frames(corners[None])[0]  # (A, 3, 3)
    away = verts - np.einsum("ak,akc->ac", bary, corners)
    local = np.linalg.solve(np.swapaxes(frame, 1, 2), away[..., None])[..., 0]  # away = local @ frame
    used, faces = np.unique(skin.faces[face], return_inverse=True)
    # the skin cut down to the faces ridden, one a vertex, and their vertices (skinned as the whole is)
    ridden = replace(
        skin, vertices=skin.vertices[used], faces=faces.reshape(-1, 3), weights=skin.weights[used]
    )
    held = _edges_among(mesh, mesh.attached)
    return SkinFaceBinding(
        mesh.attached.copy(),
        skin=ridden,
        bary=bary,
        local=local,
        held=held,
        held_lengths=np.linalg.norm(verts[held[:, 0]] - verts[held[:, 1]], axis=1),
    )


def _face_frames(corners: np.ndarray) -> np.ndarray:
    """(..., 3, 3) each triangle's two edges from its first corner and its unit normal, as rows."""
    first, second = corners[..., 1, :] - corners[..., 0, :], corners[..., 2, :] - corners[..., 0, :]
    normal = np.cross(first, second)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
    return np.stack([first, second, normal], -2)


def _edges_among(mesh: GarmentMesh, chosen: np.ndarray) -> np.ndarray:
    """(E, 2) the mesh's edges with both ends in ``chosen``, as indices into ``chosen``."""
    where = np.full(mesh.num_vertices, -1, np.int64)
    where[chosen] = np.arange(len(chosen))
    ends = where[mesh.edges()]
    return ends[(ends >= 0).all(1)]
