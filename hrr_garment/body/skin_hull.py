"""Capsules that hold the skin: a body's capsules, each widened frame by frame just enough to hold
its piece of the posed mesh the viewer sees.

    hull = skin_hull(body, skin)                 # a BodyModel fitted to a SkinnedBody
    radii = hull.radii(posed_skin, a, b)         # (T, C) for the capsules' ends a, b (T, C, 3)

Why: the push-out measures the cloth against the visible mesh (:mod:`.skin_collider`), a few
microseconds a point, but most of a garment hangs far from the body. Each face of the skin goes to
the capsule nearest to it at rest (:func:`~.mesh_collider.skinned_pieces`); a capsule widened to
reach every vertex of its piece holds the piece's triangles too (a capsule is convex), so the whole
skin lies inside the union of the widened capsules, and a point farther than ``m`` from all of
them is farther than ``m`` from the skin. Measuring every point against the capsules first (a few
nanoseconds) leaves the skin to the points within the margin of a hull. A hull is never narrower
than its capsule: the capsules lie inside the body, so the body's inside stays inside the union.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .capsules import BodyModel
from .mesh_collider import skinned_pieces
from .skinned_body import SkinnedBody

HULL_SLACK_M = 1e-6  # rounding between this measurement and the kernel's


@dataclass(frozen=True)
class SkinHull:
    """Which capsule holds each piece of the skin (see the module docstring)."""

    capsule: np.ndarray  # (n,) int64 the capsule of each (piece, vertex) pair, sorted
    vertex: np.ndarray  # (n,) int64 the skin's vertex of each pair
    starts: np.ndarray  # (C,) where each capsule's pairs start in ``capsule`` (empty: its next's)
    held: np.ndarray  # (C,) bool capsules holding a piece
    base: np.ndarray  # (C,) the capsules' own radii

    def radii(self, posed: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(T, C) each capsule's radius widened to hold its piece of the skin ``posed`` (T, V, 3),
        the capsules' ends a, b (T, C, 3) posed by the same frames."""
        p = posed[:, self.vertex]  # (T, n, 3)
        start, axis = a[:, self.capsule], b[:, self.capsule] - a[:, self.capsule]
        s = np.clip(((p - start) * axis).sum(-1) / np.maximum((axis * axis).sum(-1), 1e-12), 0.0, 1.0)[
            ..., None
        ]
        reach = np.linalg.norm(p - start - s * axis, axis=-1)  # (T, n)
        widest = np.zeros((len(posed), len(self.base)))
        widest[:, self.held] = np.maximum.reduceat(reach, self.starts[self.held], axis=1)
        return np.maximum(widest + HULL_SLACK_M, self.base)


def skin_hull(body: BodyModel, skin: SkinnedBody) -> SkinHull:
    """The pieces of ``skin`` that each capsule of ``body`` (fitted to it) holds."""
    pieces = skinned_pieces(body, skin).pieces
    capsule = np.concatenate([np.full(len(p.vertices), p.capsule) for p in pieces]).astype(np.int64)
    vertex = np.concatenate([p.vertices for p in pieces]).astype(np.int64)
    order = np.argsort(capsule, kind="stable")
    capsule, vertex = capsule[order], vertex[order]
    count = len(body.capsules)
    return SkinHull(
        capsule,
        vertex,
        np.searchsorted(capsule, np.arange(count)),
        np.isin(np.arange(count), capsule),
        np.asarray(body.radii, np.float64),
    )
