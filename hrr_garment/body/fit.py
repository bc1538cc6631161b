"""A body fitted to a mesh: the canonical skeleton with this body's bone lengths, and collision
capsules whose radii follow its surface.

    fitted = fit_body(vertices, faces, joints)   # a rest mesh and its 22 canonical joint positions
    fitted.skeleton                              # Skeleton: canonical directions, this body's lengths
    fitted.body                                  # BodyModel: the capsules, posed like the mannequin's
    fitted.report                                # how well the capsules follow the surface (mm)

The mesh may stand in any rest pose (an A-pose, as parametric bodies come, or a T-pose); its
joints give each bone's length and direction. The skeleton keeps the canonical T-pose directions
(:data:`~hrr_garment.motion.skeleton.REST_OFFSETS`) with the body's own lengths, so motion on the
canonical skeleton plays on it unchanged, limb by limb. The capsules start as the mannequin's
(:data:`~.capsules.DEFAULT_BODY`), their ends moved with the bones and their torso widths with the
body's hip and shoulder widths; each radius is then the median distance, from the capsule's axis,
of the mesh vertices nearest to that capsule (posed in the mesh's own rest pose), fitted twice so
that vertices move to the capsule that fits them. Nothing here knows where the mesh came from:
:mod:`.parametric` makes one from the parametric body, and a character's own mesh fits the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..motion.skeleton import (
    JOINT_INDEX,
    JOINT_NAMES,
    PARENTS,
    REST_OFFSETS,
    Skeleton,
    forward_kinematics,
    global_to_local,
)
from .capsules import DEFAULT_BODY, BodyModel, capsule_signed_distance

# each joint's child along its bone (the one its global rotation is aligned to); leaves keep their parent's
PRIMARY_CHILD = {
    "pelvis": "spine1",
    "spine1": "spine2",
    "spine2": "spine3",
    "spine3": "neck",
    "neck": "head",
    **{
        f"{s}_{a}": f"{s}_{b}"
        for s in "lr"
        for a, b in (
            ("hip", "knee"),
            ("knee", "ankle"),
            ("ankle", "foot"),
            ("collar", "shoulder"),
            ("shoulder", "elbow"),
            ("elbow", "wrist"),
        )
    },
}
FIT_PASSES = 2  # assign vertices to capsules, fit the radii; again with the fitted radii


@dataclass(frozen=True)
class FitReport:
    """How closely the fitted capsules follow the mesh: distances of its vertices from their surface."""

    mean_mm: float  # mean |signed distance|
    p95_mm: float  # its 95th percentile
    outside_1cm: float  # fraction of vertices more than 1 cm outside every capsule
    inside_1cm: float  # fraction of vertices more than 1 cm inside

    def to_dict(self) -> dict:
        return {
            "mean_mm": self.mean_mm,
            "p95_mm": self.p95_mm,
            "outside_1cm": self.outside_1cm,
            "inside_1cm": self.inside_1cm,
        }


@dataclass(frozen=True)
class FittedBody:
    """A body fitted to a mesh (see the module docstring)."""

    skeleton: Skeleton  # the canonical tree, T-pose directions, this body's bone lengths
    body: BodyModel  # its collision capsules
    pelvis_height: float  # metres from the soles to the pelvis in the T-pose
    report: FitReport
    stature: float  # metres from the soles to the top of the head (the mesh's)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def shortest_arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The 3 x 3 rotation taking unit direction ``a`` to unit direction ``b`` by the shortest arc."""
    a, b = _unit(np.asarray(a, np.float64)), _unit(np.asarray(b, np.float64))
    v, c = np.cross(a, b), float(np.dot(a, b))
    if c < -1.0 + 1e-9:  # opposite: half a turn about any axis perpendicular to a
        axis = _unit(np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0]))
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def body_skeleton(joints: np.ndarray) -> Skeleton:
    """The canonical skeleton with the bone lengths of ``joints`` (22, 3): each offset keeps its
    canonical direction and takes the distance between the joint and its parent in the mesh."""
    joints = np.asarray(joints, np.float64)
    offsets = np.zeros_like(REST_OFFSETS, dtype=np.float64)
    for j, p in enumerate(PARENTS):
        if p >= 0:
            offsets[j] = _unit(REST_OFFSETS[j].astype(np.float64)) * np.linalg.norm(joints[j] - joints[p])
    return Skeleton(offsets=offsets.astype(np.float32))


def rest_pose_rotations(skeleton: Skeleton, joints: np.ndarray) -> np.ndarray:
    """(22, 3, 3) global rotations that bend ``skeleton``'s T-pose into the pose of ``joints``: each
    joint's bone toward its child aligned by the shortest arc (a leaf keeps its parent's)."""
    joints = np.asarray(joints, np.float64)
    rotations = np.zeros((len(JOINT_NAMES), 3, 3))
    for j, name in enumerate(JOINT_NAMES):
        child = PRIMARY_CHILD.get(name)
        if child is None:
            rotations[j] = rotations[PARENTS[j]]
            continue
        c = JOINT_INDEX[child]
        rotations[j] = shortest_arc(skeleton.offsets[c], joints[c] - joints[j])
    return rotations


def _width(joints: np.ndarray, left: str, right: str) -> float:
    return float(np.linalg.norm(joints[JOINT_INDEX[left]] - joints[JOINT_INDEX[right]]))


def scaled_capsules(skeleton: Skeleton, joints: np.ndarray) -> BodyModel:
    """The mannequin's capsules moved onto ``skeleton``: ends on a bone follow its length, torso
    capsules' widths follow the hips' and the shoulders' (radii as the mannequin's until fitted)."""
    canonical = Skeleton()
    mannequin = canonical.rest_positions()
    ratio = {j: skeleton.bone_length(j) / max(canonical.bone_length(j), 1e-9) for j in JOINT_NAMES[1:]}
    hips = _width(joints, "l_hip", "r_hip") / _width(mannequin, "l_hip", "r_hip")
    shoulders = _width(joints, "l_shoulder", "r_shoulder") / _width(mannequin, "l_shoulder", "r_shoulder")
    torso = skeleton.bone_length("spine2") / canonical.bone_length("spine2")
    # what scales each capsule's ends: (x, y, z) factors in its joint's frame
    scale = {
        "hips": (hips, torso, torso),
        "belly": (1.0, ratio["spine2"], 1.0),
        "chest": (shoulders, torso, torso),
        "upper_chest": (shoulders, torso, torso),
        "neck": (1.0, ratio["head"], ratio["head"]),
        "head": (ratio["head"],) * 3,
    }
    for side in "lr":
        scale |= {
            f"{side}_thigh": (1.0, ratio[f"{side}_knee"], 1.0),
            f"{side}_shin": (1.0, ratio[f"{side}_ankle"], 1.0),
            f"{side}_foot": (ratio[f"{side}_foot"],) * 3,
            f"{side}_shoulder": (ratio[f"{side}_shoulder"],) * 3,
            f"{side}_upper_arm": (ratio[f"{side}_elbow"], 1.0, 1.0),
            f"{side}_forearm": (ratio[f"{side}_wrist"], 1.0, 1.0),
            f"{side}_hand": (ratio[f"{side}_wrist"],) * 3,
        }
    return BodyModel(
        tuple(
            replace(
                c,
                a=tuple(float(v) for v in np.multiply(c.a, scale[c.name])),
                b=tuple(float(v) for v in np.multiply(c.b, scale[c.name])),
            )
            for c in DEFAULT_BODY.capsules
        )
    )


def fit_radii(body: BodyModel, ends: tuple[np.ndarray, np.ndarray], vertices: np.ndarray) -> BodyModel:
    """Each capsule's radius: the median axis distance of the vertices nearest to it (by signed
    distance), :data:`FIT_PASSES` times. ``ends``: the capsules' (C, 3) ends posed like the mesh."""
    a, b = ends
    radii = body.radii.astype(np.float64)
    vertices = np.asarray(vertices, np.float64)
    for _ in range(FIT_PASSES):
        _, _, nearest = capsule_signed_distance(vertices, a, b, radii=radii)
        own = _own_axis_distance(vertices, ends, nearest)
        radii = np.array(
            [
                float(np.median(own[nearest == c])) if (nearest == c).sum() >= 3 else radii[c]
                for c in range(len(radii))
            ]
        )
    return BodyModel(tuple(replace(c, radius=float(r)) for c, r in zip(body.capsules, radii)))


def _own_axis_distance(
    vertices: np.ndarray, ends: tuple[np.ndarray, np.ndarray], capsule: np.ndarray
) -> np.ndarray:
    """(N,) each vertex's distance from the axis of its own capsule ``capsule`` (N,)."""
    a, b = ends[0][capsule], ends[1][capsule]
    ab = b - a
    s = np.clip(((vertices - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
    return np.linalg.norm(vertices - a - s[:, None] * ab, axis=-1)


def fit_body(vertices: np.ndarray, joints: np.ndarray) -> FittedBody:
    """Fit the skeleton and capsules to a rest mesh: ``vertices`` (V, 3) metres, Y up, facing +Z,
    soles at y = 0, and its canonical joints ``joints`` (22, 3) in the same pose."""
    vertices, joints = np.asarray(vertices, np.float64), np.asarray(joints, np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or len(vertices) < 50 or not np.isfinite(vertices).all():
        raise ValueError(f"a body mesh needs (V >= 50, 3) finite vertices, got {vertices.shape}")
    if joints.shape != (len(JOINT_NAMES), 3) or not np.isfinite(joints).all():
        raise ValueError(
            f"a body needs its {len(JOINT_NAMES)} canonical joints as (22, 3) finite positions, got "
            f"{joints.shape}"
        )
    skeleton = body_skeleton(joints)
    rotations = rest_pose_rotations(skeleton, joints)
    local = global_to_local(rotations[None], PARENTS)
    g_rot, g_pos = forward_kinematics(
        local, joints[None, 0], skeleton.offsets.astype(np.float64), parents=PARENTS
    )
    body = scaled_capsules(skeleton, joints)
    ends = body.pose(g_rot, g_pos)
    body = fit_radii(body, (ends[0][0], ends[1][0]), vertices)
    signed = capsule_signed_distance(vertices, ends[0][0], ends[1][0], radii=body.radii)[0]
    report = FitReport(
        mean_mm=float(np.abs(signed).mean() * 1000),
        p95_mm=float(np.quantile(np.abs(signed), 0.95) * 1000),
        outside_1cm=float((signed > 0.01).mean()),
        inside_1cm=float((signed < -0.01).mean()),
    )
    pelvis_height = _pelvis_height(skeleton, joints, vertices)
    body = replace(body, skeleton=skeleton, pelvis_height=pelvis_height)
    return FittedBody(
        skeleton, body, pelvis_height, report, stature=float(vertices[:, 1].max() - vertices[:, 1].min())
    )


def _pelvis_height(skeleton: Skeleton, joints: np.ndarray, vertices: np.ndarray) -> float:
    """The pelvis's height over the soles in the T-pose: the skeleton's pelvis-to-ankle drop plus
    how far the mesh's soles are below its ankles (the skeleton has no sole joint)."""
    ankles = [JOINT_INDEX["l_ankle"], JOINT_INDEX["r_ankle"]]
    drop = float(skeleton.rest_positions()[0, 1] - skeleton.rest_positions()[ankles, 1].mean())
    return drop + float(max(joints[ankles, 1].mean() - vertices[:, 1].min(), 0.0))


ARM_BONES = ("elbow", "wrist")  # the joints ending a side's upper arm and forearm
HAND_EXTENT = 0.5  # a hand's segment runs on past the wrist by this fraction of the forearm


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, S) each point's distance from each segment ``a[s]`` to ``b[s]``."""
    ab = b - a
    rel = points[:, None] - a[None]
    s = np.clip((rel * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12)[None], 0.0, 1.0)
    return np.linalg.norm(rel - s[..., None] * ab[None], axis=-1)


def turn_arms(vertices: np.ndarray, joints: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """A rest mesh with each arm turned rigidly about its shoulder so that shoulder-to-wrist points
    along ``directions`` ((2, 3): left, then right): a T-posed character stood in an A-pose, so that
    a body modelled in one rest pose can be compared with one modelled in another. A vertex belongs
    to an arm when its nearest bone (of the 22 joints' bones, and a hand running on past each wrist)
    is that side's upper arm, forearm or hand; each arm turns by the shortest arc, so its twist and
    the bend at its elbow are kept. ``vertices`` (V, 3) and ``joints`` (22, 3) as :func:`fit_body`
    takes them; returns the turned (V, 3) vertices (the joints are not returned: only the arms' move)."""
    vertices, joints = np.asarray(vertices, np.float64), np.asarray(joints, np.float64)
    directions = np.asarray(directions, np.float64)
    if directions.shape != (2, 3) or not np.isfinite(directions).all():
        raise ValueError(f"turn_arms needs (2, 3) directions (left, right), got {directions.shape}")
    children = [j for j, p in enumerate(PARENTS) if p >= 0]
    a, b = joints[[PARENTS[j] for j in children]], joints[children]
    labels = [JOINT_NAMES[j] for j in children]
    hands = [JOINT_INDEX[f"{s}_wrist"] for s in "lr"]
    forearm = joints[hands] - joints[[JOINT_INDEX[f"{s}_elbow"] for s in "lr"]]
    a, b = np.concatenate([a, joints[hands]]), np.concatenate([b, joints[hands] + HAND_EXTENT * forearm])
    labels += ["l_hand", "r_hand"]
    nearest = np.argmin(_segment_distance(vertices, a, b), axis=1)
    out = vertices.copy()
    for side, direction in zip("lr", directions):
        arm = [
            i
            for i, name in enumerate(labels)
            if name in (*(f"{side}_{n}" for n in ARM_BONES), f"{side}_hand")
        ]
        mask = np.isin(nearest, arm)
        shoulder = joints[JOINT_INDEX[f"{side}_shoulder"]]
        turn = shortest_arc(joints[JOINT_INDEX[f"{side}_wrist"]] - shoulder, direction)
        out[mask] = shoulder + (vertices[mask] - shoulder) @ turn.T
    return out
