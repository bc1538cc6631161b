"""Whether an ``auto`` calibration recorded in bundle.json (:mod:`hrr_garment.eval.auto_mode`) is out
of date for this version: measured before a candidate or a measurement the calibration now makes (it
is calibrated again), or, picked again under another allowance, missing the swing gains of its new
first pick (they are measured first). :mod:`hrr_garment.pipeline.auto_stage` asks."""

from __future__ import annotations

from ..artifacts.auto_calibration import AutoCalibration
from ..artifacts.manifest_entries import BodiesEntry, ResidualEntry
from ..inference.fold_track import FOLD_FOLLOW
from ..inference.swing import HALF_LIFE_S
from .auto_criterion import (
    FREE_CLOTH,
    SWING,
    SWING_GAINS,
    AutoSettings,
    candidate_setting,
    pick_auto_mode,
    swing_label,
    without_swing,
)


def followed_otherwise(auto: AutoCalibration) -> bool:
    """Whether a recorded calibration's detail candidates ran with folds followed in time otherwise
    than this version's (recorded before the following: as they came, 1)."""
    return float(1.0 if auto.fold_follow is None else auto.fold_follow) != FOLD_FOLLOW


def lacks_swing(auto: AutoCalibration) -> bool:
    """Whether a recorded calibration has no swing candidates measured as the swing now runs
    (recorded before the swing's gain, or with another half-life)."""
    return not any(SWING in k for k in auto.candidates or {}) or auto.swing_half_life_s != HALF_LIFE_S


def lacks_free_folds(auto: AutoCalibration) -> bool:
    """Whether a recorded calibration measured the detail mode before its folds were measured on
    free cloth as well (``auto.folds_free_cloth``)."""
    return not auto.folds_free_cloth and any(
        candidate_setting(k)[0] == "detail" for k in auto.candidates or {}
    )


def lacks_default_body(auto: AutoCalibration, bodies: BodiesEntry | None) -> bool:
    """Whether a recorded calibration of a model across bodies whose default is the mannequin
    (bundle.json's ``bodies``) was measured before the default body's clips were measured apart."""
    return (
        bodies is not None
        and bodies.default is None
        and bodies.count > 1
        and auto.default_body_sequences is None
    )


def lacks_free_cloth(auto: AutoCalibration, residual: ResidualEntry | None) -> bool:
    """Whether a recorded calibration measured the residual mode (of a calibrated weight,
    bundle.json's ``residual``) but not on free cloth: recorded before those candidates."""
    candidates = auto.candidates or {}
    return (
        residual is not None
        and residual.weight > 0
        and "residual" in candidates
        and not any(FREE_CLOTH in k for k in candidates)
    )


def lacks_sample(auto: AutoCalibration, sampler) -> bool:
    """Whether a model with a generative decoder (bundle.json's ``sampler``) has a calibration
    recorded without this decoder's sample mode among the candidates: trained after it, or trained
    again since (its key another)."""
    return sampler is not None and (
        "sample" not in (auto.candidates or {}) or auto.sampler_key != sampler.key
    )


def swing_unmeasured(auto: AutoCalibration, config: AutoSettings) -> bool:
    """Whether a recorded calibration's first pick under ``config`` (its pick without a swing gain)
    has swing gains not yet measured: an allowance that moves the pick needs them measured before
    picking again."""
    candidates = auto.candidates or {}
    first = pick_auto_mode(without_swing(candidates), config)
    return any(swing_label(first, gain) not in candidates for gain in SWING_GAINS)
