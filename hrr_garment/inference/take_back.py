"""The push-out's first step: what a mode adds to the regression, taken back where it carries the
cloth into the body.

The residual and detail modes (the default look is the detail mode) add to the regression what
was not made for this body in this pose: a match's departure (another simulation's cloth, on
another motion), another simulation's folds, and the swing's gain and the settling on them. (A
retrieved window is a simulation of its own, not an addition, and the regression and the sample
mode run as the torch step and the ONNX graph run them: nothing is taken back there.) Where that addition
takes a vertex into the body, pushing the vertex to the nearest surface tears the cloth: on a
character's held-out walks (issue 82) the regression alone left 4-5 % of frames for the strain
limit to repair and the default look, with its additions, 29-55 %, the torn edges' deeper ends
30-40 mm inside a thigh, where the nearest surface of two neighbours lies on opposite sides.

So each vertex the additions carry inside the body (nearer than the push's margin to it, or
inside) gets the least share of its addition that, taken back, brings it clear of the body, found
by :data:`HALVINGS` halvings; a vertex whose regression is not clear either gets the whole of it
where the regression's place is the shallower (the push takes it out from there as it takes the
regression's own cloth), none where the addition lifted it. The shares then spread over the
mesh, :data:`SPREAD_PASSES` passes of ``share = max(share, M share)`` with M the mesh's mean
operator, so that a vertex's neighbours go back with it part of the way (taken back alone, a
vertex stretched its edges to 2.7 x their rest length where the cloth as it came had 2.1), and
every vertex goes back by its share. The push-out then strain-limits the result against the cloth
as it came, as it limits its push (against a character's capsules the spread cloth still had
edges at 2.8 x), before it pushes. Measured:
docs/inference.md. The push-out's kernel runs it per frame before the push
(``hrr_garment/native/push_out.c``: take_back_frame); this module is its reference.

The regression's cloth is ``base``: the same frames decoded from the regression's own latents
(:attr:`~.gate.WindowChoice.regression`), stood on the body and taken to the world as the cloth is.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix

from ..body.capsules import frames_signed_distance

HALVINGS = 3  # a share found to within an eighth of the addition (the kernel's TAKE_BACK_HALVINGS)
SPREAD_PASSES = 4  # the shares' spread over the mesh (TAKE_BACK_PASSES); 2 passes already undid the stretch
MOVED_M = 1e-6  # an addition no longer than this is none (TAKE_BACK_MOVED)


def take_back(
    vertices: np.ndarray, base: np.ndarray, body, margin: float, mean: csr_matrix | None = None
) -> np.ndarray:
    """(T, V, 3) world vertices and (T, V, 3) the regression's (``base``) -> a copy with each vertex
    gone back towards ``base`` by its share of its addition (the module docstring): for a vertex
    nearer than ``margin`` to ``body`` or inside it, the least that takes it ``margin`` clear; where
    ``base`` is not clear, the whole if ``base`` is the shallower, else none; then spread over the
    mesh by ``mean`` (its :func:`~hrr_garment.garment.smoothing.mean_operator`; None: not spread). ``body``:
    :class:`~.visible_push.PosedSkin` (the mesh the viewer sees) or
    :class:`~.collision.PosedCapsules`, posed for the T frames."""
    if vertices.shape != base.shape:
        raise ValueError(f"the cloth {vertices.shape} and the regression's {base.shape} differ in shape")
    from .visible_push import PosedSkin

    skin = body if isinstance(body, PosedSkin) else None
    hulls = body.hulls if skin is not None else body
    radii = np.broadcast_to(hulls.radii, hulls.a.shape[:2])
    points = np.asarray(vertices, np.float64)
    addition = points - np.asarray(base, np.float64)
    # the hulls hold the skin: a vertex past the margin of every hull is past it of the skin
    hull, _ = frames_signed_distance(points, hulls.a, hulls.b, radii=radii)
    near = (hull < margin) & (np.linalg.norm(addition, axis=-1) > MOVED_M)
    out = points.copy()
    for t in np.flatnonzero(near.any(1)):

        def distance(p: np.ndarray, t: int = t) -> np.ndarray:
            if skin is not None:
                return skin.frame_distance(t, p, margin)
            rows = slice(t, t + 1)
            return frames_signed_distance(p[None], hulls.a[rows], hulls.b[rows], radii=radii[rows])[0][0]

        rows = np.flatnonzero(near[t])
        came = distance(points[t, rows])
        rows, came = rows[came < margin], came[came < margin]
        under = distance(points[t, rows] - addition[t, rows])
        share = np.zeros(len(points[t]))
        # where the regression is not clear either: all the way back where it is the shallower, else none
        share[rows[(under < margin) & (under > came)]] = 1.0
        left = rows[under >= margin]
        lo, hi = np.zeros(len(left)), np.ones(len(left))  # not clear at lo, clear at hi
        for _ in range(HALVINGS):
            mid = (lo + hi) / 2
            ok = distance(points[t, left] - mid[:, None] * addition[t, left]) >= margin
            hi, lo = np.where(ok, mid, hi), np.where(ok, lo, mid)
        share[left] = hi
        for _ in range(SPREAD_PASSES if mean is not None else 0):
            share = np.maximum(share, mean @ share)
        out[t] -= share[:, None] * addition[t]
    return out.astype(vertices.dtype, copy=False)
