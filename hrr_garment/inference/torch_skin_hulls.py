"""The visible mesh's hulls as a torch module that ONNX can hold: each capsule grown, frame by frame,
to hold its pieces of the posed skin (:mod:`hrr_garment.body.skin_envelope`, the push-out's broad
phase; ``VisibleCollider.skinned`` gives the same radii in the kernel), never narrower than the
capsule. The push-out's graph measures a point against the skin only within its margin of a hull,
as the package's does: farther out the hull's distance is the distance (a lower bound on the skin's,
more than the margin), where the collider alone can call a point between the thighs, across the gap
from the nearest skin, inside."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from .torch_ops import constant


class SkinHulls(nn.Module):
    """The envelope's pieces (points on the skin's faces, each with its capsule) as buffers."""

    def __init__(self, envelope) -> None:
        super().__init__()
        constant(self, "corners", envelope.corners, dtype=torch.int64)  # (P, 3) vertices of its face
        constant(self, "bary", envelope.bary[..., None])  # (P, 3, 1) its place on the face
        constant(self, "capsule", envelope.capsule, dtype=torch.int64)  # (P,)
        # each capsule's pieces as a padded table (C, K), the padding a piece of its own that never
        # wins (its reach -inf), so that a capsule's growth is one gather and one max
        capsules = len(envelope.body.radii)
        held = [np.flatnonzero(envelope.capsule == c) for c in range(capsules)]
        width = max(1, max(len(h) for h in held))
        pad = len(envelope.capsule)
        table = np.full((capsules, width), pad, np.int64)
        for c, rows in enumerate(held):
            table[c, : len(rows)] = rows
        constant(self, "table", table, dtype=torch.int64)

    def forward(
        self, posed: torch.Tensor, a: torch.Tensor, b: torch.Tensor, radii: torch.Tensor
    ) -> torch.Tensor:
        """(N, C) the hulls' radii of the skins posed (N, V, 3), the capsules' ends (N, C, 3) and
        their radii (C,)."""
        points = (posed[:, self.corners] * self.bary).sum(-2)  # (N, P, 3)
        pa, pb = a[:, self.capsule], b[:, self.capsule]
        outside = segment_distance(points, pa, pb) - radii[self.capsule]  # (N, P)
        padded = torch.cat([outside, torch.full_like(outside[:, :1], float("-inf"))], 1)
        growth = padded[:, self.table].amax(-1)  # (N, C)
        return torch.maximum(radii + growth, radii.expand_as(growth))


def segment_distance(p: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Distance (...,) of points p (..., 3) to the segments a-b (..., 3)."""
    ab = b - a
    s = torch.clamp(((p - a) * ab).sum(-1) / torch.clamp((ab * ab).sum(-1), min=1e-12), 0.0, 1.0)
    return torch.linalg.vector_norm(p - a - s[..., None] * ab, dim=-1)
