"""The push-out's wrap: a patch of cloth deep in a limb put onto the limb around its own centre.

Projecting each vertex of a patch that lies ``d`` deep in a limb of radius ``r`` straight out onto
the surface stretches the patch around the limb by ``r / (r - d)``: 25 mm deep in a 60 mm forearm
is 1.7 x, past the strain limit's 1.5 (decisions 0023 and 0032 measured those tears). The wrap
puts a vertex at distance ``rho`` from the capsule's axis and angle ``phi`` from its patch's
centre direction ``u0`` on the surface at angle ``phi * rho / r`` from ``u0``: the arc lengths
about the axis are kept (``rho dphi``), the radial ones shortened, and the map is the identity on
the surface, so continuous with the cloth outside. A patch: the vertices within the margin of one
capsule (nearest it) joined by edges; ``u0`` their outward directions weighted by how far each must
move, square to the axis on the capsule's cylinder. A vertex already within the margin outside
(``rho`` of at least ``r``) goes straight out, as before.

This module is the reference (numpy, one frame at a time); the push-out's kernel does the same
(:mod:`hrr_garment.native`). docs/decisions/0038-push-out-wrap.md.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def wrap_displacements(p: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray, d: np.ndarray, margin: float,
                       edges: np.ndarray) -> np.ndarray:
    """One frame: vertices ``p`` (V, 3) float64, capsule ends ``a``, ``b`` (C, 3), ``radii`` (C,),
    the vertices' signed distances ``d`` (V,) and the garment's ``edges`` (E, 2) -> (V, 3) the move of
    each vertex within ``margin`` of the body to its wrapped place ``margin`` outside (0 elsewhere)."""
    out = np.zeros_like(p)
    hit = np.flatnonzero(d < margin)
    if not len(hit):
        return out
    q = p[hit]
    ab = b - a
    l2 = np.maximum((ab * ab).sum(-1), 1e-12)
    s_all = np.clip(((q[:, None] - a[None]) * ab[None]).sum(-1) / l2, 0.0, 1.0)  # (H, C)
    rel = q[:, None] - a[None] - s_all[..., None] * ab[None]
    rho_all = np.sqrt((rel * rel).sum(-1))
    cap = (rho_all - radii[None]).argmin(1)  # the nearest capsule, as the distances chose it
    rows = np.arange(len(hit))
    s, u, rho, r = s_all[rows, cap], rel[rows, cap], rho_all[rows, cap], radii[cap]
    uhat = u / np.maximum(rho, 1e-12)[:, None]
    weight = margin - d[hit]
    # the patches: hit vertices of one capsule joined by an edge
    local = np.full(len(p), -1)
    local[hit] = rows
    e = edges[(local[edges[:, 0]] >= 0) & (local[edges[:, 1]] >= 0)]
    e = e[cap[local[e[:, 0]]] == cap[local[e[:, 1]]]]
    graph = coo_matrix((np.ones(len(e)), (local[e[:, 0]], local[e[:, 1]])), shape=(len(hit), len(hit)))
    _, patch = connected_components(graph, directed=False)
    centre = np.zeros((patch.max() + 1, 3))
    np.add.at(centre, patch, weight[:, None] * uhat)
    u0 = centre[patch]
    axis = ab[cap] / np.sqrt(l2[cap])[:, None]
    cylinder = (s > 0.0) & (s < 1.0)
    u0 = np.where(cylinder[:, None], u0 - (u0 * axis).sum(1, keepdims=True) * axis, u0)
    norm = np.linalg.norm(u0, axis=1)
    # a patch with no side of its own (a vertex alone on the axis): a fixed direction square to it
    square = np.cross(axis, np.eye(3)[np.abs(axis).argmin(1)])
    fallback = np.where((rho > 1e-12)[:, None], uhat, square / np.linalg.norm(square, axis=1, keepdims=True))
    u0 = np.where((norm > 1e-9)[:, None], u0 / np.maximum(norm, 1e-12)[:, None], fallback)
    cos = np.clip((uhat * u0).sum(1), -1.0, 1.0)
    perp = uhat - cos[:, None] * u0
    pn = np.linalg.norm(perp, axis=1)
    # opposite the centre (or on the axis) any square direction: the one about the axis
    side = np.cross(axis, u0)
    perp = np.where((pn > 1e-9)[:, None], perp / np.maximum(pn, 1e-12)[:, None], side)
    angle = np.arctan2(pn, cos) * np.minimum(rho / r, 1.0)  # the angle from u0 (arccos loses digits near 0)
    direction = np.cos(angle)[:, None] * u0 + np.sin(angle)[:, None] * perp
    direction /= np.maximum(np.linalg.norm(direction, axis=1), 1e-12)[:, None]
    foot = q - u
    out[hit] = foot + (r + margin)[:, None] * direction - q
    return out
