"""The detail mode's last step: the regression's shape with simulated folds.

Regression gives the conditional mean of a chaotic cloth, accurate but smooth; a database frame
is a real simulation, sharp but one sample whose large-scale shape may be far from this motion's.
A frequency split keeps the best of each: the regression's low spatial frequencies (where the
dress is) and the simulated frames' high ones (their folds and wrinkles, from the bundle's
:class:`~hrr_garment.artifacts.folds.FoldStore`, chosen by the :mod:`.fold_track`). With H the
high-pass of the store (:func:`~hrr_garment.garment.smoothing.high_frequencies`),

    detail = regression + strength * follow(folds - H(regression))

which swaps the regression's own high frequencies for ``strength`` x the simulated ones (the
strength is calibrated per model with the auto mode: :mod:`hrr_garment.eval.auto_mode`). H removes
anything constant over the mesh and commutes with rotations, so this holds in the body frame and in
the world alike. ``follow`` is the fold term's smoothing in time (:func:`~.fold_track.follow_folds`,
the identity where none is given): the term, not the folds alone, so that the regression's own high
frequencies, which it replaces, are smoothed alike. Measured on held-out real clips: docs/results.md.

*Free cloth.* Where the cloth lies on the body (a bodice), a matched frame's folds are its contact
with another pose, on another body for a model across bodies, and they put cloth inside this one.
The auto calibration may weight the term per vertex by how far the vertex hangs from the body at
rest (0 within ``lo`` mm, 1 beyond ``hi``: bundle.json ``auto.folds_free_mm``, the same ramps as the
residual's, :data:`~hrr_garment.artifacts.free_cloth.FREE_CLOTH_RAMPS_MM`): the skirt takes the
simulated folds, the bodice keeps the regression's shape. On the unseen tall-slim body this took the
folds' share of the cloth inside before the push-out from 0.34 to 0.06 points
(docs/decisions/0028-folds-on-free-cloth.md).

Folds from another simulation can stretch an edge of this shape far past what any simulation does
(2.3 x its rest length on held-out clips). Where they would take an edge past
:data:`FOLD_MAX_STRAIN` and longer than the regression has it, the edge-length projection of the
push-out (:func:`~.strain_limit.limit_push_strain`) takes back as much of them as it must; elsewhere
the folds are untouched. On 6 held-out real clips this capped the strain max at 1.52 (from 2.28)
with PVE, sharpness and jitter unchanged (0.84 to 0.83 bending energy ratio).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.sparse import csr_matrix

from ..artifacts.folds import DETAIL_STRENGTH
from ..garment.smoothing import high_frequencies
from .edge_limits import EdgeLimits
from .strain_limit import limit_push_strain

FOLD_MAX_STRAIN = 1.5  # x rest length: the push-out's own limit (strain_limit.MAX_PUSH_STRAIN)
# projection passes: on folds out of place ten take the strain max where sixty do, in a quarter of
# the time (tools/bench_checks.py: the limit's share of a crowd's step)
FOLD_LIMIT_ITERATIONS = 10


def add_folds(
    regression: np.ndarray,
    folds: np.ndarray,
    mean: csr_matrix,
    passes: int,
    strength: float = DETAIL_STRENGTH,
    limits: EdgeLimits | None = None,
    follow: Callable[[np.ndarray], np.ndarray] | None = None,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """(T, V, 3) regression vertices and (T, V, 3) folds (high frequencies at ``passes`` passes of
    ``mean``, the mesh's :func:`~hrr_garment.garment.smoothing.mean_operator`; same frame, body or
    world) -> (T, V, 3) float32; with the template's ``limits``, no edge stretched by the folds past
    :data:`FOLD_MAX_STRAIN`; ``follow``: the fold term's smoothing in time (module docstring);
    ``weights``: (V, 1) the term's weight per vertex (the bundle's folds on free cloth), None: 1."""
    term = folds - high_frequencies(regression, mean, passes)
    if weights is not None:
        term = term * weights
    if follow is not None:
        term = follow(term)
    detail = (regression + strength * term).astype(np.float32)
    if limits is None:
        return detail
    return limit_push_strain(
        detail,
        regression,
        limits,
        max_strain=FOLD_MAX_STRAIN,
        iterations=FOLD_LIMIT_ITERATIONS,
        in_place=True,
    )[0].astype(np.float32, copy=False)
