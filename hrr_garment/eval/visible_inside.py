"""Cloth inside the body the viewer sees: hrr-eval's headline plausibility figure (docs/evaluation.md).

    visible = visible_body_of(record.dressed.record)     # what a viewer sees of the body
    share = inside_visible(vertices, motion, visible)     # (T,) fraction of the garment's vertices
    figures = inside_before_and_after(before, after, motion, visible=visible)  # hrr-eval's four, in %

A game draws the character's skinned mesh, not the 20 capsules the push-out works against, so the
figure counts the garment's vertices inside that mesh, posed by linear blend skinning
(:mod:`hrr_garment.body.skinned_body`) frame by frame, and farther inside than
:data:`~hrr_garment.sim.quality.PENETRATION_DEPTH_M` (5 mm, the capsule figure's threshold, so the two
compare) along the exact distance to the mesh; inside by the winding number
(:mod:`hrr_garment.body.mesh_inside`: every frame, exact). What the viewer sees of a body
(:class:`VisibleBody`'s ``kind``):

- ``mesh``: an anny body's skinned mesh, or a fitted character's own, which its body.json carries
  (:func:`~hrr_garment.body.skinned_body.visible_body`);
- ``capsules``: a body with no mesh of its own (the mannequin, a body scaled from it): previews draw
  it as its capsules, so they are its visible body and the figure is the capsule figure itself;
- ``unknown``: a body fitted to a character's mesh whose body.json does not carry the mesh (written
  before format 2, or a mesh without skin weights), or an anny body without anny installed: the
  figure is unknown (NaN, null in report.json) and the reports say so beside the capsule figure,
  never passing that off as the mesh's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..body.body_file import BodyRecord
from ..body.capsules import DEFAULT_BODY, BodyModel
from ..body.mesh_inside import inside_deeper_than, is_closed
from ..body.skinned_body import SkinnedBody, visible_body
from ..motion.motion import Motion
from ..sim.quality import PENETRATION_DEPTH_M, body_signed_distance

MESH, CAPSULES, UNKNOWN = "mesh", "capsules", "unknown"  # VisibleBody.kind
# the figures, percent: before and after the push-out, the mean over frames and the worst frame
SHARES = (
    "inside_visible_before_pct",
    "inside_visible_before_worst_pct",
    "inside_visible_pct",
    "inside_visible_worst_pct",
)
POINTS_PER_PASS = 50_000  # garment vertices measured at once (all frames of a pass: tens of MB)


@dataclass(frozen=True)
class VisibleBody:
    """What a viewer sees of a body: its skinned ``mesh`` (kind ``mesh``), its ``capsules`` (a body with
    no mesh of its own: kind ``capsules``), or nothing known (kind ``unknown``)."""

    kind: str
    capsules: BodyModel
    mesh: SkinnedBody | None = None
    closed: bool = True  # the mesh is closed (its winding number an integer: the fast exact test)

    @classmethod
    def of_mesh(cls, mesh: SkinnedBody, capsules: BodyModel) -> "VisibleBody":
        """The visible body that is ``mesh`` (whether it is closed found once, here)."""
        return cls(MESH, capsules, mesh, is_closed(mesh.faces))


def visible_body_of(record: BodyRecord | None) -> VisibleBody:
    """What a viewer sees of the body ``record`` (None: the mannequin); see the module docstring."""
    if record is None:
        return VisibleBody(CAPSULES, DEFAULT_BODY)
    mesh = visible_body(record)
    if mesh is not None:
        return VisibleBody.of_mesh(mesh, record.body)
    if record.shape or record.report is not None:  # anny missing; a character's mesh not in body.json
        return VisibleBody(UNKNOWN, record.body)
    return VisibleBody(CAPSULES, record.body)


def deep_inside(
    vertices: np.ndarray,
    motion: Motion,
    visible: VisibleBody,
    *,
    where: np.ndarray | None = None,
    depth: float = PENETRATION_DEPTH_M,
) -> np.ndarray:
    """(T, V) whether each of the garment's world ``vertices`` (T, V, 3) lies more than ``depth`` inside
    the body ``visible`` (a mesh, or capsules: not an unknown one) as ``motion`` poses it; on a mesh,
    only the vertices ``where`` holds (T, V) are measured (the others False)."""
    if visible.kind == CAPSULES:
        return body_signed_distance(vertices, motion, visible.capsules) < -depth
    mesh, step = visible.mesh, max(1, POINTS_PER_PASS // vertices.shape[1])
    deep = []
    for t in range(0, len(vertices), step):  # frames at once, as many as keep the arrays small
        posed = mesh.pose(motion.global_rotations[t : t + step], motion.joint_positions[t : t + step])
        deep.append(
            inside_deeper_than(
                vertices[t : t + step],
                posed,
                mesh.faces,
                depth=depth,
                closed=visible.closed,
                where=None if where is None else where[t : t + step],
            )
        )
    return np.concatenate(deep)


def inside_visible(vertices: np.ndarray, motion: Motion, visible: VisibleBody) -> np.ndarray:
    """(T,) the fraction of the garment's world ``vertices`` (T, V, 3) more than 5 mm inside the body
    ``visible`` as ``motion`` poses it; NaN on every frame where the visible body is unknown."""
    if visible.kind == UNKNOWN:
        return np.full(len(vertices), np.nan)
    return deep_inside(vertices, motion, visible).mean(1)


def inside_before_and_after(
    before: np.ndarray, after: np.ndarray, motion: Motion, *, visible: VisibleBody
) -> dict[str, float]:
    """The cloth inside the visible body before the push-out (``before``, (T, V, 3)) and after it
    (``after``), in percent: ``inside_visible_before_pct`` and ``inside_visible_pct`` (the mean over
    frames) with their ``_worst_pct`` (the worst frame); NaN where the visible body is unknown. Only the
    vertices the push-out moved are measured again after it."""
    if visible.kind == UNKNOWN:
        return dict.fromkeys(SHARES, math.nan)
    deep_before = deep_inside(before, motion, visible)
    moved = (np.asarray(after) != np.asarray(before)).any(-1)
    deep_after = deep_before.copy()
    if moved.any():
        deep_after[moved] = deep_inside(after, motion, visible, where=moved)[moved]
    out = {}
    for prefix, deep in (("inside_visible_before", deep_before), ("inside_visible", deep_after)):
        share = deep.mean(1)
        out.update(
            {f"{prefix}_pct": 100.0 * float(share.mean()), f"{prefix}_worst_pct": 100.0 * float(share.max())}
        )
    return out
