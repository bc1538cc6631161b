"""How much of the cloth a model puts inside a body before the push-out: a model's own answer to
"will it animate my character?", beside the training bodies' range of measures.

    report = cloth_inside(animator, motion, "hero.json")
    report.inside_visible_pct  # vertices more than 5 mm inside the body the viewer sees, mean over frames (%)
    report.inside_pct          # ... inside its capsules

The range (:class:`~hrr_garment.body.measures.BodyRange`) checks each of a body's measures on its
own; the model learns the shapes of the bodies it saw, so a body inside every measure's range but
with other proportions can still take the cloth inside it (docs/results-bodies.md: the mannequin
scaled 1.05-1.1 x, 5-11 %, against 0.1-0.3 % on anny's bodies). The push-out takes the cloth out
again; what it has to move is what tears (docs/inference.md). The body the viewer sees is its skinned
mesh, not the capsules the push-out works against (:mod:`.visible_inside`): the cloth inside it leads.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field

from ..inference.animator import Animator
from ..motion.motion import Motion
from ..motion.synth import synthesize
from ..sim.quality import body_signed_distance, penetration_fraction
from .visible_inside import inside_visible, visible_body_of

CHECK_SECONDS = 6.0  # the procedural walk a body is checked on: a curve, both legs forward and back


@dataclass(frozen=True)
class InsideReport:
    """The cloth inside one body on one clip, before the push-out (percent of the garment's vertices)."""

    body_name: str
    stature_m: float
    # more than 5 mm inside the body the viewer sees, the mean over frames (NaN: that body unknown)
    inside_visible_pct: float
    inside_visible_worst_pct: float  # ... on the worst frame
    visible_body: str  # what that is: "mesh", "capsules" (a body with no mesh) or "unknown"
    inside_pct: float  # more than 5 mm inside, the mean over frames (hrr-eval's "inside before the push-out")
    inside_worst_pct: float  # ... on the worst frame
    inside_any_pct: float  # inside at all, the mean over frames
    outside_range: list[str] = field(default_factory=list)  # the measures outside the model's training range

    def to_dict(self) -> dict:
        return asdict(self)


def check_motion() -> Motion:
    """The clip a body is checked on when none is given: the procedural curved walk."""
    return synthesize("walk_curve", CHECK_SECONDS, seed=0)


def cloth_inside(animator: Animator, motion: Motion, body=None, *, name: str | None = None) -> InsideReport:
    """The model's garment on ``body`` (anything :meth:`Animator.body` takes; None: the model's own)
    playing ``motion`` in its default mode, offline, the push-out off, measured against the body the
    viewer sees and against its capsules (``name``: the body's name in the report). A body outside
    the model's range is animated anyway and its measures that are out listed."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the measures out of range are reported instead
        character = animator.body(body, allow_outside=True, name=name)
        animation = animator.animate(motion, body=character, push_out=False)
    distance = body_signed_distance(
        animation.vertices, animation.skeleton, character.body
    )  # the clip as the body played it
    deep = penetration_fraction(distance)
    visible = visible_body_of(character.record)
    seen = inside_visible(animation.vertices, animation.skeleton, visible)
    return InsideReport(
        body_name=character.name,
        stature_m=float(character.record.stature),
        inside_visible_pct=100.0 * float(seen.mean()),
        inside_visible_worst_pct=100.0 * float(seen.max()),
        visible_body=visible.kind,
        inside_pct=100.0 * float(deep.mean()),
        inside_worst_pct=100.0 * float(deep.max()),
        inside_any_pct=100.0 * float((distance < 0).mean()),
        outside_range=animator.bundle.body_range.outside(character.vector),
    )
