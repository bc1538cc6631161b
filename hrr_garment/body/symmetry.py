"""A body beside its mirror image (x -> -x): whether it is symmetric, and made exactly so where it
nearly is, so that a sequence on it can be mirrored onto the same body."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..motion.skeleton import MIRROR_JOINTS, Skeleton
from .capsules import BodyModel


@dataclass(frozen=True)
class _Halves:
    """A body beside its mirror image (x -> -x): the skeleton's offsets and each capsule's ends and
    radius, next to those of its left-right partner reflected (a capsule across the midline is its
    own partner, its ends swapped where that matches)."""

    offsets: np.ndarray  # (22, 3)
    mirrored_offsets: np.ndarray
    ends: np.ndarray  # (C, 2, 3)
    mirrored_ends: np.ndarray
    radii: np.ndarray  # (C,)
    mirrored_radii: np.ndarray

    def gap(self) -> float:
        """The largest left-right difference, metres."""
        return float(
            max(
                np.abs(self.mirrored_offsets - self.offsets).max(),
                np.abs(self.mirrored_ends - self.ends).max(),
                np.abs(self.mirrored_radii - self.radii).max(),
            )
        )


def _halves(body: BodyModel) -> _Halves | None:
    """``body`` beside its mirror image, or None where a capsule has no left-right partner."""
    flip = np.array([-1.0, 1.0, 1.0])
    by_name = {c.name: c for c in body.capsules}
    if any(_mirror_name(c.name) not in by_name for c in body.capsules):
        return None
    ends, mirrored = [], []
    for c in body.capsules:
        other = by_name[_mirror_name(c.name)]
        mine, theirs = np.array([c.a, c.b]), np.array([other.a, other.b]) * flip
        if other is c:  # a capsule across the midline mirrors onto itself with its ends swapped
            theirs = (
                theirs[::-1] if np.abs(theirs[::-1] - mine).max() < np.abs(theirs - mine).max() else theirs
            )
        ends.append(mine)
        mirrored.append(theirs)
    offsets = np.asarray(body.skeleton.offsets, np.float64)
    radii = body.radii.astype(np.float64)
    index = {c.name: i for i, c in enumerate(body.capsules)}
    partner = [index[_mirror_name(c.name)] for c in body.capsules]
    return _Halves(
        offsets,
        offsets[list(MIRROR_JOINTS)] * flip,
        np.array(ends),
        np.array(mirrored),
        radii,
        radii[partner],
    )


def is_symmetric(body: BodyModel, tolerance: float = 1e-3) -> bool:
    """Whether ``body`` is its own mirror image (x -> -x) within ``tolerance`` metres: left and right
    bones of one length, capsules in mirrored places with equal radii. A sequence on it can be
    mirrored exactly; on an asymmetric body the mirror would stand on another body."""
    halves = _halves(body)
    return halves is not None and halves.gap() <= tolerance


# a body whose left and right differ by less is made exactly symmetric: anny's bodies are, but their
# fitted capsules differ side to side by up to 1 cm in a bone and 2.5 cm in a shoulder's radius
# (the vertices between shoulder and upper arm split differently on each side)
NEARLY_SYMMETRIC_M = 0.03


def symmetrized(body: BodyModel, tolerance: float = NEARLY_SYMMETRIC_M) -> BodyModel:
    """``body`` with left and right averaged, where they differ by less than ``tolerance`` (made
    exact, its sequences can be mirrored); else ``body`` as it is."""
    halves = _halves(body)
    if halves is None or halves.gap() > tolerance:
        return body
    ends = 0.5 * (halves.ends + halves.mirrored_ends)
    radii = 0.5 * (halves.radii + halves.mirrored_radii)
    capsules = tuple(
        replace(c, a=tuple(float(v) for v in e[0]), b=tuple(float(v) for v in e[1]), radius=float(r))
        for c, e, r in zip(body.capsules, ends, radii)
    )
    skeleton = Skeleton(offsets=(0.5 * (halves.offsets + halves.mirrored_offsets)).astype(np.float32))
    return replace(body, capsules=capsules, skeleton=skeleton)


def symmetrized_record(record):
    """A body record (:class:`~.body_file.BodyRecord`) on its :func:`symmetrized` body and that body's
    skeleton: the body a garment is dressed on and a clip is played by (so also the skeleton an
    exported character must stand on to play that clip)."""
    body = symmetrized(record.body)
    return replace(record, body=body, skeleton=body.skeleton)


def _mirror_name(name: str) -> str:
    if name.startswith("l_"):
        return "r_" + name[2:]
    if name.startswith("r_"):
        return "l_" + name[2:]
    return name
