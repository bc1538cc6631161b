"""A garment moved from the body it was made for onto another body, keeping its topology.

    on_b = transfer_garment(garment, made_for=body_a, body=body_b)   # same vertices, faces, groups

Every vertex is written in coordinates relative to each capsule of the body it was made for, both
in their rest poses (:meth:`~hrr_garment.body.capsules.BodyModel.rest_pose`): where along the
capsule's axis it lies, which way from the axis, and how far outside its surface. Each capsule
carries the vertex onto the other body by the same three numbers (the bone's length and direction,
the capsule's radius): a vertex 12 mm off a thigh stays 12 mm off the other body's thigh, so the
garment neither floats nor sinks. The vertex's new place blends the capsules' answers with weights
that fall off with its distance from each (:data:`BLEND_M`), so the mapping is smooth where two
capsules meet and the cloth does not tear between them. A last push moves any vertex left closer
than ``min_gap`` to the new body out along the surface normal.

The mannequin's templates go onto other bodies this way when a dataset simulates one garment on
many bodies (one topology for every body, :mod:`hrr_garment.sim.body_plan`), and so does a garment
of your own declared with the body it was modelled on (``--made-for``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..body.capsules import BodyModel, capsule_signed_distance
from .clearance import ClearanceReport
from .mesh import GarmentMesh

BLEND_M = (
    0.02  # a capsule's weight falls by e for each 2 cm a vertex lies farther from it than from the nearest
)
MIN_GAP_M = 0.004  # no vertex closer to the new body than this after the transfer
PUSH_PASSES = 4


@dataclass(frozen=True)
class TransferReport:
    """How the transfer placed the garment on the new body (rest poses, metres)."""

    inside: float  # fraction of vertices inside the new body before the last push
    pushed: float  # fraction moved by the last push
    gap_change_mean_mm: float  # mean |distance to the new body - distance to the old| after the push
    moved_mean_mm: (
        float  # mean distance of each vertex from where it was modelled (onto the same body: the push alone)
    )
    visible: ClearanceReport | None = None  # then kept clear of the body's visible mesh (dressing.dress)


def _capsule_frames(body: BodyModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a, b = body.rest_pose()
    return np.asarray(a, np.float64), np.asarray(b, np.float64), body.radii.astype(np.float64)


def _rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(C, 3, 3) rotations taking unit vectors u (C, 3) onto v (C, 3) by the shortest arc."""
    w = np.cross(u, v)
    c = (u * v).sum(-1)
    k = np.zeros((len(u), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    k = k - k.transpose(0, 2, 1)
    return np.eye(3)[None] + k + k @ k / np.maximum(1.0 + c, 1e-9)[:, None, None]


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def transfer_points(points: np.ndarray, made_for: BodyModel, body: BodyModel) -> np.ndarray:
    """``points`` (N, 3) around ``made_for`` in its rest pose, carried to ``body``'s rest pose (no push)."""
    if [c.name for c in made_for.capsules] != [c.name for c in body.capsules]:
        raise ValueError("the two bodies must have the same capsules (the same names in the same order)")
    p = np.asarray(points, np.float64)
    a0, b0, r0 = _capsule_frames(made_for)
    a1, b1, r1 = _capsule_frames(body)
    axis0, axis1 = b0 - a0, b1 - a1
    length0 = np.maximum(np.linalg.norm(axis0, axis=-1), 1e-9)
    length1 = np.linalg.norm(axis1, axis=-1)
    turn = _rotation_between(_unit(axis0), _unit(axis1))  # a sphere (zero-length capsule) keeps its frame
    rel = p[:, None] - a0[None]  # (N, C, 3)
    t = np.clip((rel * axis0[None]).sum(-1) / length0[None] ** 2, 0.0, 1.0)
    radial = rel - t[..., None] * axis0[None]  # from the axis's nearest point to the vertex
    distance = np.linalg.norm(radial, axis=-1)
    surface = distance - r0[None]  # signed distance from each capsule
    # the same place on each capsule of the new body: along its axis, turned with the bone, as far
    # outside its surface (the radial length grows or shrinks by the change of radius)
    stretch = np.maximum(distance + (r1 - r0)[None], 0.0) / np.maximum(distance, 1e-9)
    moved = (
        a1[None]
        + t[..., None] * _unit(axis1)[None] * length1[None, :, None]
        + np.einsum("cij,ncj->nci", turn, radial) * stretch[..., None]
    )
    weight = np.exp(-(surface - surface.min(1, keepdims=True)) / BLEND_M)
    weight /= weight.sum(1, keepdims=True)
    return (weight[..., None] * moved).sum(1)


def transfer_garment(
    garment: GarmentMesh, *, made_for: BodyModel, body: BodyModel, min_gap: float = MIN_GAP_M
) -> tuple[GarmentMesh, TransferReport]:
    """``garment`` (in ``made_for``'s rest pose) on ``body``: the same topology and groups, each
    vertex as far outside the new body as it was outside the old (see the module docstring)."""
    moved = transfer_points(garment.vertices, made_for, body)
    a1, b1, r1 = _capsule_frames(body)
    before = capsule_signed_distance(moved, a1, b1, radii=r1)[0]
    start = moved.copy()
    for _ in range(PUSH_PASSES):  # where two capsules meet, one push can land inside the other
        distance, normal, _ = capsule_signed_distance(moved, a1, b1, radii=r1)
        moved = moved + np.maximum(min_gap - distance, 0.0)[:, None] * normal
    push = np.linalg.norm(moved - start, axis=-1)
    a0, b0, r0 = _capsule_frames(made_for)
    old = capsule_signed_distance(np.asarray(garment.vertices, np.float64), a0, b0, radii=r0)[0]
    new = capsule_signed_distance(moved, a1, b1, radii=r1)[0]
    report = TransferReport(
        inside=float((before < 0).mean()),
        pushed=float((push > 0).mean()),
        gap_change_mean_mm=float(np.abs(new - old).mean() * 1000),
        moved_mean_mm=float(np.linalg.norm(moved - garment.vertices, axis=-1).mean() * 1000),
    )
    return replace(garment, vertices=moved.astype(np.float32)), report
