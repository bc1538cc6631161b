"""Letting go of a limb that tears the cloth: the push-out's answer where a limb passes through it.

Where a limb passes through the cloth (a forearm through the bodice, a hand sunk into the hips with
the dress between them, a stride's thigh through the skirt), no push out of that limb can keep the
cloth whole: the vertices inside it go out of its nearest surface, half one way and half the other,
and the strain limit then undoes part of the push. Measured on real-quick's 16 test clips, the
push-out of the *simulated* cloth itself tore 28 % of the frames (131_03 93 %, a bye wave 100 %),
nearly all where the capture's own arms sink into the body or rest on it: the simulator lets the
arms through the cloth there (:mod:`hrr_garment.sim.simulator`), so the truth has arms through the
dress, and a model that learns it does too.

So a frame the push tore is pushed again without the limb capsules holding the torn cloth: the
vertices the strain limit moved lie inside (or within the push's margin of) those capsules as the
cloth came. The torso never lets go; a limb released on one frame pushes
again on the next. On the simulated test clips (their own cloth pushed out, the mannequin's
capsules) the frames the strain limit acts on went from 28.1 % to 0.53 %, the cloth left more than
5 mm inside the capsules after the push from 0.083 % to 0.11 % of the vertices (the arms the
simulator let through the dress); on the trained real-quick model from 42.9 to 21.3 %, but with
four times the cloth left inside the body (0.14 to 0.63 %), so it is an option, off by default
(``PushOutSettings.release_limbs``; docs/decisions/0041). The visible mesh has no capsules to let
go of: its push-out tears as before.
"""

from __future__ import annotations

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, each_capsule_signed_distance
from ..body.self_contact import LEG_PARTS, LOWER_ARM, UPPER_ARM

RELEASED_RADIUS = -1e3  # a released capsule's radius: every point a kilometre outside it
LIMB_PARTS = UPPER_ARM + LOWER_ARM + LEG_PARTS  # the capsules that may let go (left and right)


def limb_capsules(body: BodyModel | None = None) -> np.ndarray:
    """Indices of the limb capsules of ``body`` (default: the canonical layout every body shares)."""
    names = [c.name for c in (body or DEFAULT_BODY).capsules]
    return np.array([i for i, n in enumerate(names) if n.split("_", 1)[-1] in LIMB_PARTS], np.int64)


def held_limbs(
    repaired: np.ndarray,
    unpushed: np.ndarray,
    ends: tuple[np.ndarray, np.ndarray, np.ndarray],
    margin: float,
    limbs: np.ndarray,
) -> np.ndarray:
    """(T, C) the limb capsules to let go of: those within ``margin`` of a vertex the strain limit
    moved (``repaired`` (T, V)) where the push took it (``unpushed`` (T, V, 3)); the capsules' ends
    (T, C, 3) and radii (T, C) as pushed."""
    a, b, radii = ends
    out = np.zeros(radii.shape, bool)
    for t in np.flatnonzero(repaired.any(1)):
        x = unpushed[t, repaired[t]].astype(np.float64)
        gap = each_capsule_signed_distance(x, a[t, limbs], b[t, limbs], radii=radii[t, limbs])  # (k, L)
        out[t, limbs[(gap < margin).any(0)]] = True
    return out
