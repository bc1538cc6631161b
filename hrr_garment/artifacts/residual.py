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

*Free cloth.* Where the cloth lies on the body (a bodice), the match's deviation is another
simulation's contact, on another body for a model across bodies: it puts cloth inside the body.
Where the cloth hangs free (a skirt) it is the swing the regression lacks. The residual can be
weighted per latent node (each a region of the garment) by how far that region hangs from the body
at rest: 0 within ``lo`` mm, 1 beyond ``hi`` mm (:func:`free_cloth_weights`). Whether and with
which ramp (:data:`FREE_CLOTH_RAMPS_MM`) is the auto calibration's choice on validation
(:mod:`hrr_garment.eval.auto_mode`), recorded as bundle.json ``auto.residual_free_mm``.
"""

from __future__ import annotations

import numpy as np
import torch

from ..body.capsules import BodyModel, capsule_signed_distance
from ..models.codes import encode_motion
from .database import CodeDatabase

#: the weights the calibration tries (0, plain regression, is always among the candidates)
RESIDUAL_WEIGHTS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
#: the calibrated weight is the largest whose validation error is at most this times regression's:
#: the most borrowed detail for a bounded loss of accuracy (issue 23 asks a detail mode for at most
#: 1.03 x regression-only PVE with sharpness). Against one chaotic truth, window error alone always
#: prefers the mean (weight 0), which is what the regression mode already gives.
ACCURACY_ALLOWANCE = 1.03
#: the free-cloth ramps (lo, hi) in mm the auto calibration tries beside the plain residual: at rest
#: the dress's bodice nodes sit at its 12 mm clearance, its skirt's at 34-300 mm
FREE_CLOTH_RAMPS_MM = ((10.0, 40.0), (20.0, 60.0))


def rest_hang_m(rest_vertices: np.ndarray, body: BodyModel) -> np.ndarray:
    """(V,) how far each vertex of the garment at rest on ``body`` (``rest_vertices`` (V, 3)) hangs
    from it (metres, signed: negative inside)."""
    a, b = body.rest_pose()
    return capsule_signed_distance(np.asarray(rest_vertices, np.float64), a, b, radii=body.radii)[0].astype(
        np.float32
    )


def free_cloth_weights(hang_m: np.ndarray, ramp_mm: tuple[float, float]) -> np.ndarray:
    """(nodes,) float32 the residual's weight per node: 0 where the node hangs within ``lo`` mm of
    the body, 1 beyond ``hi`` mm, linear between (``ramp_mm`` = (lo, hi), lo < hi; negative: inside)."""
    lo, hi = (float(x) / 1000.0 for x in ramp_mm)
    if not -np.inf < lo < hi < np.inf:
        raise ValueError(f"a free-cloth ramp is (lo, hi) mm with lo < hi, got {tuple(ramp_mm)}")
    return np.clip((np.asarray(hang_m, np.float64) - lo) / (hi - lo), 0.0, 1.0).astype(np.float32)


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
