"""The detail mode's last step: the regression's shape with simulated folds.

Regression gives the conditional mean of a chaotic cloth, accurate but smooth; a database frame
is a real simulation, sharp but one sample whose large-scale shape may be far from this motion's.
A frequency split keeps the best of each: the regression's low spatial frequencies (where the
dress is) and the simulated frames' high ones (their folds and wrinkles, from the bundle's
:class:`~hrr_garment.artifacts.folds.FoldStore`, chosen by the :mod:`.fold_track`). With H the
high-pass of the store (:func:`~hrr_garment.garment.smoothing.high_frequencies`),

    detail = regression + strength * (folds - H(regression))

which swaps the regression's own high frequencies for ``strength`` x the simulated ones (the
strength is calibrated per model with the auto mode: :mod:`hrr_garment.eval.auto_mode`). H removes
anything constant over the mesh and commutes with rotations, so this holds in the body frame and in
the world alike. Measured on held-out real clips: docs/results.md.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix

from ..artifacts.folds import DETAIL_STRENGTH
from ..garment.smoothing import high_frequencies


def add_folds(regression: np.ndarray, folds: np.ndarray, mean: csr_matrix, passes: int,
              strength: float = DETAIL_STRENGTH) -> np.ndarray:
    """(T, V, 3) regression vertices and (T, V, 3) folds (high frequencies at ``passes`` passes of
    ``mean``, the mesh's :func:`~hrr_garment.garment.smoothing.mean_operator`; same frame, body or
    world) -> (T, V, 3) float32."""
    own = high_frequencies(regression, mean, passes)
    return (regression + strength * (folds - own)).astype(np.float32)
