"""Residual retrieval: the regression plus the detail of the retrieved window.

Regression predicts the conditional mean, which is smooth; a retrieved database window is a real
simulation, sharp but only one sample of a chaotic cloth. Residual retrieval keeps the mean and
adds what the match has that the regressor cannot predict, its *residual*: the match's true
latents minus the regression of the match's own motion. Where the query's motion is the match's,
the two regressions cancel and the result is the match itself; elsewhere the residual carries the
match's folds and swing onto the regression's shape, not the match's pose. Scaled by the match's
code similarity (how many code groups it shares with the query: a poor match adds little) and by
one weight per model, calibrated on validation like tau
(:mod:`hrr_garment.train.residual_calibration`): the most detail within
:data:`ACCURACY_ALLOWANCE` of the regression's error.

Unreal Engine's ML Deformer went the same way, from nearest-neighbour poses to a regression plus
the residual detail of the matched poses.

Where the cloth hangs free the residual is its swing, where it lies on the body another simulation's
contact: the residual weighted by region, :mod:`hrr_garment.artifacts.free_cloth`.
"""

from __future__ import annotations

import numpy as np
import torch

from ..models.codes import encode_motion
from .database import CodeDatabase

#: the weights the calibration tries (0, plain regression, is always among the candidates)
RESIDUAL_WEIGHTS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
#: the calibrated weight is the largest whose validation error is at most this times regression's:
#: the most borrowed detail for a bounded loss of accuracy (issue 23 asks a detail mode for at most
#: 1.03 x regression-only PVE with sharpness). Against one chaotic truth, window error alone always
#: prefers the mean (weight 0), which is what the regression mode already gives.
ACCURACY_ALLOWANCE = 1.03


def match_regression(
    codespace,
    motion_stats,
    latent_stats,
    database: CodeDatabase,
    rows: np.ndarray,
    last_frame: bool = False,
    step: torch.nn.Module | None = None,
) -> np.ndarray:
    """What the regression predicts for the database windows ``rows`` (Q,) from their own motion:
    (Q, W or 1, nodes, C) latents, not standardised (``step``, ``last_frame``: as
    :func:`~hrr_garment.models.codes.encode_motion`, so causal inference repeats its own bits)."""
    if database.motion is None:
        raise ValueError("this database has no motion windows (residual retrieval needs them)")
    raw = motion_stats.denormalize(database.motion[rows])
    return encode_motion(
        codespace,
        motion_stats,
        latent_stats,
        motion_windows=raw,
        regression=True,
        last_frame=last_frame,
        step=step,
    ).regression


def residual_scale(similarity: np.ndarray, weight: float, nodes: np.ndarray | None = None) -> np.ndarray:
    """(N, 1, nodes or 1, 1) weight x similarity x nodes: how much of each window's match departure
    the residual adds (``nodes``: the free-cloth weights, :func:`free_cloth_weights`; None: 1)."""
    scale = (float(weight) * np.asarray(similarity, np.float32)).reshape(-1, 1, 1, 1)
    if nodes is not None:
        scale = scale * np.asarray(nodes, np.float32).reshape(1, 1, -1, 1)
    return scale


def residual_latents(
    regression: np.ndarray,
    matched: np.ndarray,
    matched_regression: np.ndarray,
    similarity: np.ndarray,
    weight: float,
    nodes: np.ndarray | None = None,
) -> np.ndarray:
    """regression + weight x similarity x nodes x (matched - matched_regression), per window:
    latents (N, W, nodes, C) each, similarity (N,) in [0, 1], ``nodes`` (nodes,) the free-cloth
    weights (:func:`free_cloth_weights`; None: 1 everywhere)."""
    scale = residual_scale(similarity, weight, nodes)
    return (regression + scale * (matched - matched_regression)).astype(np.float32)
