"""Cloth inside the body the viewer sees: hrr-eval's headline plausibility figure (docs/evaluation.md).

    visible = visible_body_of(record.dressed.record)     # what a viewer sees of the body
    share = inside_visible(vertices, motion, visible)     # (T,) fraction of the garment's vertices

A game draws the character's skinned mesh, not the 20 capsules the push-out works against, so the
figure counts the garment's vertices inside that mesh, posed by linear blend skinning
(:mod:`hrr_garment.body.skinned_body`) frame by frame, and farther inside than
:data:`~hrr_garment.sim.quality.PENETRATION_DEPTH_M` (5 mm, the capsule figure's threshold, so the two
compare) along the exact distance to the mesh; inside by the winding number
(:mod:`hrr_garment.body.mesh_inside`: every frame, exact). What the viewer sees of a body
(:class:`VisibleBody`'s ``kind``):

- ``mesh``: an anny body's skinned mesh (:func:`~hrr_garment.body.skinned_body.visible_body`);
- ``capsules``: a body with no mesh of its own (the mannequin, a body scaled from it): previews draw
  it as its capsules, so they are its visible body and the figure is the capsule figure itself;
- ``unknown``: a body fitted to a character's mesh (``hrr-body fit``), whose body.json does not carry
  the mesh, or an anny body without anny installed: the figure is unknown (NaN, null in report.json)
  and the reports say so beside the capsule figure, never passing that off as the mesh's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..body.body_file import BodyRecord
from ..body.capsules import DEFAULT_BODY, BodyModel
from ..body.mesh_inside import inside_deeper_than, is_closed
from ..body.skinned_body import SkinnedBody, visible_body
from ..motion.motion import Motion
from ..sim.quality import PENETRATION_DEPTH_M, body_signed_distance, penetration_fraction

MESH, CAPSULES, UNKNOWN = "mesh", "capsules", "unknown"  # VisibleBody.kind


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
        return cls(MESH, capsules, mesh, is_closed(mesh.faces))


def visible_body_of(record: BodyRecord | None) -> VisibleBody:
    """What a viewer sees of the body ``record`` (None: the mannequin); see the module docstring."""
    if record is None:
        return VisibleBody(CAPSULES, DEFAULT_BODY)
    if record.shape:
        mesh = visible_body(record)
        return (
            VisibleBody.of_mesh(mesh, record.body) if mesh is not None else VisibleBody(UNKNOWN, record.body)
        )
    if record.report is not None:  # fitted to a character's mesh, which body.json does not hold
        return VisibleBody(UNKNOWN, record.body)
    return VisibleBody(CAPSULES, record.body)


def inside_visible(
    vertices: np.ndarray, motion: Motion, visible: VisibleBody, depth: float = PENETRATION_DEPTH_M
) -> np.ndarray:
    """(T,) the fraction of the garment's world ``vertices`` (T, V, 3) more than ``depth`` inside the
    body ``visible`` as ``motion`` poses it; NaN on every frame where the visible body is unknown."""
    if visible.kind == UNKNOWN:
        return np.full(len(vertices), np.nan)
    if visible.kind == CAPSULES:
        return penetration_fraction(body_signed_distance(vertices, motion, visible.capsules), depth)
    mesh = visible.mesh
    posed = mesh.pose(motion.global_rotations, motion.joint_positions)
    return np.array(
        [
            inside_deeper_than(v, p, mesh.faces, depth=depth, closed=visible.closed).mean()
            for v, p in zip(vertices, posed)
        ]
    )


def inside_visible_pct(
    vertices: np.ndarray, motion: Motion, visible: VisibleBody, *, prefix: str = "inside_visible"
) -> dict[str, float]:
    """``{prefix}_pct`` (the mean over frames) and ``{prefix}_worst_pct`` (the worst frame), in percent."""
    share = inside_visible(vertices, motion, visible)
    return {f"{prefix}_pct": 100.0 * float(share.mean()), f"{prefix}_worst_pct": 100.0 * float(share.max())}
