"""The residual mode's calibration (:mod:`hrr_garment.artifacts.residual`), on the windows the
gate is calibrated on (:mod:`.calibration_windows`): its weight is the largest of 0 (plain
regression) and :data:`~hrr_garment.artifacts.residual.RESIDUAL_WEIGHTS` whose mean error stays
within :data:`~hrr_garment.artifacts.residual.ACCURACY_ALLOWANCE` of the regression's."""

from __future__ import annotations

import numpy as np
from tqdm import tqdm

from ..artifacts.bundle import Bundle
from ..artifacts.bundle_writer import BundleParts
from ..artifacts.residual import ACCURACY_ALLOWANCE, RESIDUAL_WEIGHTS
from .calibration_windows import (
    MAX_WINDOWS,
    WindowPredictions,
    calibration_windows,
    predict_windows,
    window_errors_mm,
)


def residual_errors(
    pred: WindowPredictions, decode, truth: np.ndarray, progress: bool = False
) -> dict[float, np.ndarray] | None:
    """Per-window errors (mm) of the residual mode at each of :data:`RESIDUAL_WEIGHTS` (None where
    the database has no motion windows to regress the matches from)."""
    if pred.match_regression is None:
        return None
    return {
        w: window_errors_mm(decode, pred.residual(w), truth)
        for w in tqdm(RESIDUAL_WEIGHTS, desc="residual weights", unit="weight", disable=not progress)
    }


def calibrate_residual(
    model: BundleParts | Bundle,
    motion: dict[str, np.ndarray],
    frames: dict[str, np.ndarray],
    windows: list[tuple[str, int]] | None = None,
    max_windows: int | None = MAX_WINDOWS,
) -> dict:
    """The residual mode's calibration alone (:meth:`ModeErrors.residual_calibration`), on the
    windows :func:`window_mode_errors` uses: for a model trained before the residual mode."""
    _, m, truth = calibration_windows(
        motion, frames, model.codespace.config.window, windows=windows, max_windows=max_windows
    )
    pred = predict_windows(
        model.codespace, m, model.motion_stats, latent_stats=model.latent_stats, database=model.database
    )
    if pred.match_regression is None:
        raise ValueError("the database has no motion windows: the residual mode cannot run on this model")
    decode = model.autoencoder.inference_decoder()
    return choose_residual_weight(
        window_errors_mm(decode, pred.regression, truth), residual_errors(pred, decode, truth)
    )


def choose_residual_weight(
    regression_err: np.ndarray, residual_err: dict[float, np.ndarray], allowance: float = ACCURACY_ALLOWANCE
) -> dict:
    """The largest weight (0: regression) whose mean error is at most ``allowance`` x the
    regression's, its error, and every weight's."""
    errors = {0.0: float(np.mean(regression_err)), **{w: float(np.mean(e)) for w, e in residual_err.items()}}
    weight = max(w for w, e in errors.items() if w == 0.0 or e <= allowance * errors[0.0])
    return {
        "weight": weight,
        "validation_mm": errors[weight],
        "allowance": allowance,
        "errors_mm": {str(w): e for w, e in errors.items()},
    }
