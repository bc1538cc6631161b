"""Distances to a body's capsules in the operators ONNX has, for the exportable push-out
(:mod:`.torch_push_out`): every vertex of a crowd against its character's capsules
(:func:`capsule_depths`, :func:`capsule_distance_within`), and the few points a push moves, each
against its own character's (:func:`point_capsule_distance`).

Written for onnxruntime's CPU kernels, which set the step's cost here: passes over (N, V, C) of a
32-character crowd cost a few tenths of a millisecond each; products broadcast over a last axis of
3, sums over a middle axis, transposes with a last axis of 3 and batches of one-row products all
run many times slower than the same work on whole planes. So the crowd's distances take as few
(N, V, C) passes as the algebra allows, the normals are measured only where a push reads them
(:func:`capsule_distance_within`), and those few points are measured a coordinate at a time."""

from __future__ import annotations

import torch


def point_capsule_distance(points: torch.Tensor, capsules: tuple) -> tuple[torch.Tensor, torch.Tensor]:
    """(K,) signed distances and (K, 3) outward normals of points (K, 3), each to the union of its
    own ``capsules``: the ends a, b given coordinate by coordinate, (3, K, C), and the radii (K, C)
    (:func:`per_point`): for the few points a push moves, on (K, C) planes, which onnxruntime
    runs 2.3 x faster than (K, 3, C) and (K, C, 3) (14,000 points)."""
    a, b, radii = capsules
    ax, ay, az = a[0], a[1], a[2]
    ex, ey, ez = b[0] - ax, b[1] - ay, b[2] - az
    rx, ry, rz = points[:, 0:1] - ax, points[:, 1:2] - ay, points[:, 2:3] - az
    along = (rx * ex + ry * ey + rz * ez) / torch.clamp(ex * ex + ey * ey + ez * ez, min=1e-12)
    s = torch.clamp(along, 0.0, 1.0)
    dx, dy, dz = rx - s * ex, ry - s * ey, rz - s * ez
    length = torch.sqrt(dx * dx + dy * dy + dz * dz)  # (K, C)
    d, nearest = (length - radii).min(-1)
    pick = lambda x: torch.gather(x, 1, nearest[:, None])  # noqa: E731
    return d, torch.cat([pick(dx), pick(dy), pick(dz)], 1) / torch.clamp(pick(length), min=1e-12)


def capsule_depths(p: torch.Tensor, a: torch.Tensor, b: torch.Tensor, *, radii: torch.Tensor) -> torch.Tensor:
    """The signed distances (N, V) of points (N, V, 3) to the union of capsules a-b (N, C, 3) of
    ``radii`` (N, 1, C), in a dozen passes over (N, V, C): two products give (p - a) . ab (twice)
    and |p - a|^2, the terms a point and a capsule share folded into their columns."""
    ab = b - a  # (N, C, 3)
    ab_ab = (ab * ab).sum(-1)[:, None]  # (N, 1, C)
    ones = torch.ones_like(p[..., :1])
    # [p, 1] . [2 ab, -2 a.ab] = 2 (p - a) . ab; [p, |p|^2, 1] . [-2 a, 1, |a|^2] = |p - a|^2
    twice = torch.cat([2.0 * ab, -2.0 * (a * ab).sum(-1, keepdim=True)], -1)
    square = torch.cat([-2.0 * a, torch.ones_like(a[..., :1]), (a * a).sum(-1, keepdim=True)], -1)
    rel_ab2 = torch.cat([p, ones], -1) @ twice.transpose(1, 2)  # (N, V, C)
    rel_rel = torch.cat([p, (p * p).sum(-1, keepdim=True), ones], -1) @ square.transpose(1, 2)
    s = torch.clamp(rel_ab2 * (0.5 / torch.clamp(ab_ab, min=1e-12)), 0.0, 1.0)
    axis2 = rel_rel - s * (rel_ab2 - s * ab_ab)  # |p - a - s ab|^2
    return (torch.sqrt(torch.clamp(axis2, min=0.0)) - radii).amin(-1)


def capsule_distance_within(
    p: torch.Tensor, a: torch.Tensor, b: torch.Tensor, *, radii: torch.Tensor, within: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`capsule_depths` (``radii`` (N, 1, C) or (C,)) and the nearest capsule's outward
    normals (N, V, 3), measured only where the distance is under ``within`` (by
    :func:`point_capsule_distance`) and zero elsewhere."""
    d = capsule_depths(p, a, b, radii=radii)
    rows = torch.nonzero((d < within).reshape(-1))[:, 0]
    radii = radii.reshape(-1, radii.shape[-1]).expand(p.shape[0], -1)  # (N, C): each character's, or one set
    _, normals = capsule_distance_at(p, rows, ends=(a, b), radii=radii)
    return d, torch.zeros_like(p).reshape(-1, 3).index_copy(0, rows, normals).reshape(p.shape)


def capsule_distance_at(
    p: torch.Tensor, rows: torch.Tensor, *, ends: tuple, radii: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """(K,) distances and (K, 3) normals of the points (N, V, 3) at the flat (character x vertex)
    ``rows`` (K,), each against its character's capsules: ``ends`` a, b (N, C, 3), ``radii`` (N, C)."""
    character = torch.div(rows, p.shape[1], rounding_mode="floor")
    points = torch.index_select(p.reshape(-1, 3), 0, rows)
    return point_capsule_distance(points, per_point(character, *ends, radii=radii))


def per_point(character: torch.Tensor, a: torch.Tensor, b: torch.Tensor, *, radii: torch.Tensor) -> tuple:
    """The capsules of each point's ``character`` (K,) as :func:`point_capsule_distance` takes them:
    the ends (N, C, 3) as (3, K, C), the radii (N, C) as (K, C). The characters' ends are turned
    before they are gathered (onnxruntime turns a (K, C, 3) at some 50 ns an element)."""
    ends = (torch.index_select(x.permute(2, 0, 1), 1, character) for x in (a, b))
    return (*ends, torch.index_select(radii, 0, character))
