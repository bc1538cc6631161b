"""The collision body: capsules rigidly attached to the canonical bones.

Each capsule is a segment [a, b] given in one joint's local frame plus a radius, so posing is one
rigid transform per capsule. The same capsules drive the cloth simulator's colliders, the signed
distance used for penetration metrics and collision push-out, and the preview mesh.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..motion.motion import Motion
from ..motion.skeleton import CANONICAL, JOINT_INDEX, REST_OFFSETS, REST_PELVIS_HEIGHT, Skeleton


@dataclass(frozen=True)
class Capsule:
    """One capsule of the body: end points ``a`` and ``b`` relative to ``joint``, and its radius."""

    name: str
    joint: str
    a: tuple[float, float, float]
    b: tuple[float, float, float]
    radius: float


def _off(name: str) -> tuple[float, float, float]:
    return tuple(float(v) for v in REST_OFFSETS[JOINT_INDEX[name]])  # type: ignore[return-value]


def _default_capsules() -> tuple[Capsule, ...]:
    caps = [
        Capsule("hips", "pelvis", (0.075, -0.06, -0.01), (-0.075, -0.06, -0.01), 0.115),
        Capsule("belly", "spine1", (0.0, 0.0, 0.0), _off("spine2"), 0.115),
        Capsule("chest", "spine2", (0.05, 0.03, 0.0), (-0.05, 0.03, 0.0), 0.11),
        Capsule("upper_chest", "spine3", (0.055, 0.08, 0.0), (-0.055, 0.08, 0.0), 0.10),
        Capsule("neck", "neck", (0.0, 0.0, 0.0), _off("head"), 0.05),
        Capsule("head", "head", (0.0, 0.05, 0.01), (0.0, 0.09, 0.01), 0.095),
    ]
    for side, s in (("l", 1.0), ("r", -1.0)):
        caps += [
            Capsule(f"{side}_thigh", f"{side}_hip", (0.0, -0.02, 0.0), _off(f"{side}_knee"), 0.075),
            Capsule(f"{side}_shin", f"{side}_knee", (0.0, 0.0, 0.0), _off(f"{side}_ankle"), 0.052),
            Capsule(f"{side}_foot", f"{side}_ankle", (0.0, -0.035, -0.02), (0.0, -0.045, 0.15), 0.04),
            Capsule(f"{side}_shoulder", f"{side}_collar", (0.0, 0.0, 0.0), _off(f"{side}_shoulder"), 0.055),
            Capsule(f"{side}_upper_arm", f"{side}_shoulder", (0.0, 0.0, 0.0), _off(f"{side}_elbow"), 0.047),
            Capsule(f"{side}_forearm", f"{side}_elbow", (0.0, 0.0, 0.0), _off(f"{side}_wrist"), 0.037),
            Capsule(f"{side}_hand", f"{side}_wrist", (0.0, 0.0, 0.0), (s * 0.09, 0.0, 0.0), 0.035),
        ]
    return tuple(caps)


@dataclass(frozen=True, eq=False)
class BodyModel:
    """A set of capsules on a skeleton; ``scaled(k)`` makes all radii k times larger (a fuller or
    slimmer body). ``skeleton`` and ``pelvis_height`` place the body in its rest pose (the
    mannequin's by default; a fitted body's own, :mod:`.fit`): motion carries its own skeleton."""

    capsules: tuple[Capsule, ...] = field(default_factory=_default_capsules)
    skeleton: Skeleton = CANONICAL
    pelvis_height: float = REST_PELVIS_HEIGHT  # metres from the soles to the pelvis in the rest pose

    def scaled(self, radius_scale: float) -> "BodyModel":
        return replace(
            self, capsules=tuple(replace(c, radius=c.radius * radius_scale) for c in self.capsules)
        )

    @property
    def is_mannequin_frame(self) -> bool:
        """Whether it stands on the mannequin's skeleton at the mannequin's height."""
        return self.skeleton is CANONICAL and self.pelvis_height == REST_PELVIS_HEIGHT

    @property
    def radii(self) -> np.ndarray:
        return np.array([c.radius for c in self.capsules])

    @cached_property
    def ends(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each capsule's joint index (C,) and its end points a, b (C, 3) in that joint's frame."""
        return (
            np.array([JOINT_INDEX[c.joint] for c in self.capsules]),
            np.array([c.a for c in self.capsules]),
            np.array([c.b for c in self.capsules]),
        )

    def pose(
        self, global_rotations: np.ndarray, joint_positions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """World capsule end points (T, C, 3) each for a and b, from FK results (T, 22, ...)."""
        joints, a, b = self.ends
        return pose_ends(global_rotations, joint_positions, joints, a=a, b=b)

    def pose_motion(self, motion: Motion) -> tuple[np.ndarray, np.ndarray]:
        return self.pose(motion.global_rotations, motion.joint_positions)

    def rest_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Capsule ends a, b (C, 3) in its skeleton's T-pose, standing on the ground."""
        rot = np.broadcast_to(np.eye(3), (1, len(REST_OFFSETS), 3, 3))
        a, b = self.pose(rot, self.rest_joints()[None])
        return a[0], b[0]

    def rest_joints(self) -> np.ndarray:
        """(22, 3) joint positions of its skeleton's T-pose, the pelvis over the origin."""
        if self.is_mannequin_frame:
            return rest_joint_positions()
        return self.skeleton.rest_positions(np.array([0.0, self.pelvis_height, 0.0]))


def pose_ends(
    global_rotations: np.ndarray,
    joint_positions: np.ndarray,
    joints: np.ndarray,
    *,
    a: np.ndarray,
    b: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """World capsule end points (T, C, 3) each: ends ``a``, ``b`` in their ``joints``' frames, (C, 3)
    shared by every frame or (T, C, 3) each frame's own (a crowd's characters of different bodies),
    posed by FK results (T, 22, 3, 3) and (T, 22, 3)."""
    rot, pos = global_rotations[:, joints], joint_positions[:, joints]
    return pos + np.einsum("...cij,...cj->...ci", rot, a), pos + np.einsum("...cij,...cj->...ci", rot, b)


def rest_joint_positions() -> np.ndarray:
    """(22, 3) joint positions of the canonical rest pose standing at the origin."""
    return CANONICAL.rest_positions(np.array([0.0, REST_PELVIS_HEIGHT, 0.0]))


DEFAULT_BODY = BodyModel()


def capsule_signed_distance(
    points: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed distance from points (N, 3) to the union of capsules (C) with ends a, b (C, 3).

    Returns (distance (N,), outward unit normal of the nearest capsule (N, 3), its index (N,)).
    Negative distances are inside the body. Exact for the union (the minimum over capsules).
    """
    diff, dist_axis = _axis_gaps(points, a, b)
    sd = dist_axis - radii[None]
    nearest = sd.argmin(1)
    rows = np.arange(points.shape[0])
    d = diff[rows, nearest]
    n = d / np.maximum(dist_axis[rows, nearest], 1e-12)[:, None]
    return sd[rows, nearest], n, nearest


def each_capsule_signed_distance(
    points: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray
) -> np.ndarray:
    """(N, C) signed distance from each point (N, 3) to each capsule (ends a, b (C, 3), radii (C,))."""
    return _axis_gaps(points, a, b)[1] - radii[None]


def _axis_gaps(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's (N, 3) offset from each capsule's axis segment (N, C, 3) and its length (N, C)."""
    ab = b - a  # (C, 3)
    denom = np.maximum((ab * ab).sum(-1), 1e-12)
    rel = points[:, None, :] - a[None]  # (N, C, 3)
    s = np.clip((rel * ab[None]).sum(-1) / denom, 0.0, 1.0)
    diff = rel - s[..., None] * ab[None]
    return diff, np.sqrt((diff * diff).sum(-1))


def frames_signed_distance(
    points: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`capsule_signed_distance` frame by frame: points (T, N, 3) against each frame's capsule
    ends a, b (T, C, 3) and radii (C,), or each frame's own (T, C) -> distances (T, N) and normals
    (T, N, 3). Runs in the native kernel of :mod:`hrr_garment.native` when it is compiled (equal to
    1e-12, tested)."""
    from ..native import default_threads, load_kernel
    from ..native.capsules import capsule_sdf

    lib = load_kernel()
    per_frame = np.ndim(radii) == 2
    if lib is not None and not per_frame:
        return capsule_sdf(lib, points, a, b=b, radii=radii, threads=default_threads())
    out = [
        capsule_signed_distance(
            np.asarray(points[t], np.float64), a[t], b[t], radii[t] if per_frame else radii
        )[:2]
        for t in range(len(points))
    ]
    return np.stack([o[0] for o in out]), np.stack([o[1] for o in out])


def _unit_capsule(segments: int = 16, rings: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A unit sphere split at its equator: vertices, faces, and which end (0=a, 1=b) each belongs to."""
    theta = np.linspace(0, np.pi, 2 * rings + 1)  # from +z pole to -z pole, equator duplicated below
    theta = np.concatenate([theta[: rings + 1], theta[rings:]])
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    tt, pp = np.meshgrid(theta, phi, indexing="ij")
    verts = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1).reshape(-1, 3)
    end = np.repeat((np.arange(len(theta)) > rings).astype(int), segments)  # upper half -> b, lower -> a
    end = 1 - end
    faces = []
    for i in range(len(theta) - 1):
        for j in range(segments):
            v0, v1 = i * segments + j, i * segments + (j + 1) % segments
            v2, v3 = v0 + segments, v1 + segments
            faces += [(v0, v2, v1), (v1, v2, v3)]
    faces_arr = np.array(faces)
    # Drop degenerate triangles at the poles (measured with the halves apart: the duplicated
    # equator rings coincide on the unit sphere but bound the cylinder between the ends).
    tri = (verts + end[:, None] * np.array([0.0, 0.0, 1.0]))[faces_arr]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return verts, faces_arr[area > 1e-9], end


def body_mesh(
    a: np.ndarray, b: np.ndarray, radii: np.ndarray, segments: int = 16, rings: int = 8
) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh (vertices, faces) of the capsules of one frame (a, b: (C, 3)); for previews."""
    unit, faces, end = _unit_capsule(segments, rings)
    all_v, all_f = [], []
    for c in range(len(radii)):
        axis = b[c] - a[c]
        length = np.linalg.norm(axis)
        z = axis / length if length > 1e-9 else np.array([0.0, 0.0, 1.0])
        x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        frame = np.stack([x, np.cross(z, x), z], 1)
        centre = np.where(end[:, None] == 1, b[c], a[c])
        all_f.append(faces + sum(len(v) for v in all_v))
        all_v.append(centre + radii[c] * unit @ frame.T)
    return np.concatenate(all_v), np.concatenate(all_f)
