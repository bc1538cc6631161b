"""Calibration (hrr_garment.train.calibrate): mode errors on a window sample, the tau sweep, the
choice of the gate signal and of the residual weight."""

import math

import numpy as np
import pytest

from hrr_garment.artifacts.gate_signals import GATE_SIGNALS
from hrr_garment.train.calibrate import ModeErrors
from hrr_garment.train.residual_calibration import choose_residual_weight
from hrr_garment.train.tau_sweep import sweep_tau


def test_calibration_on_a_window_sample_is_the_sample_of_the_full_errors(trained):
    """max_windows keeps evenly spaced windows: their errors are exactly those windows' full errors."""
    from hrr_garment.artifacts.bundle_loader import load_bundle
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.data.windows import dataset_features
    from hrr_garment.train.calibrate import window_mode_errors
    from hrr_garment.train.training_frames import body_frames

    root, data, _ = trained
    bundle, ds = load_bundle(root / "model"), GarmentDataset(data)
    names = ds.splits["val"]
    args = (
        bundle,
        dataset_features(ds, names, bundle.codespace.config),
        {n: body_frames(ds, [n]) for n in names},
    )
    encoding = {"refine_steps": 0, "refine_lr": 0.0}
    full = window_mode_errors(*args, encoding=encoding, max_windows=None)
    sample = window_mode_errors(*args, encoding=encoding, max_windows=7)
    keep = np.linspace(0, len(full.regression) - 1, 7).round().astype(int)
    assert len(full.regression) > 7 and len(sample.regression) == 7
    for field in ("regression", "retrieval", "autoencoder", "entropy"):
        np.testing.assert_allclose(getattr(sample, field), getattr(full, field)[keep], rtol=1e-5, atol=1e-4)


def test_the_sweep_ends_at_a_finite_threshold_that_retrieves_everything():
    doubt = np.array([0.1, 0.4, 0.9])
    sweep = sweep_tau(doubt, np.array([1.0, 1.0, 1.0]), np.array([0.0, 0.0, 0.0]))
    assert all(math.isfinite(t) for t in sweep.taus)
    assert sweep.retrieval_usage[-1] == 1.0 and sweep.taus[-1] > doubt.max()
    assert (
        sweep.retrieval_usage[sweep.taus.index(sweep.best_tau)] == 1.0
    )  # the smallest tau that retrieves all


def _mode_errors(doubts: dict) -> ModeErrors:
    reg, ret = np.array([2.0, 2.0, 2.0, 2.0]), np.array([1.0, 3.0, 3.0, 1.0])
    return ModeErrors(reg, ret, np.zeros(4), doubts, {g: sweep_tau(d, reg, ret) for g, d in doubts.items()})


def test_calibration_picks_the_signal_that_separates_the_good_matches():
    """Retrieval is better on windows 0 and 3: the distance ranks them first, the entropy does not."""
    errors = _mode_errors(
        {
            "entropy": np.array([0.5, 0.1, 0.2, 0.6]),
            "similarity": np.array([0.3, 0.3, 0.3, 0.3]),
            "distance": np.array([0.1, 0.8, 0.9, 0.2]),
        }
    )
    assert errors.gate == "distance" and min(errors.sweep.errors_mm) == pytest.approx(1.5)
    assert errors.summary(errors.sweep.best_tau, "distance")["retrieval_usage"] == 0.5
    gates = errors.gates()
    assert set(gates) == {"entropy", "similarity", "distance"} and gates["distance"][
        "validation_mm"
    ] == pytest.approx(1.5)


def test_calibration_keeps_the_papers_entropy_on_a_tie():
    same = np.array([0.1, 0.2, 0.3, 0.4])
    assert _mode_errors({g: same for g in GATE_SIGNALS}).gate == "entropy"


def test_the_calibration_keeps_the_most_detail_within_the_accuracy_allowance():
    regression = np.array([2.0, 2.0])
    tried = {0.25: np.array([2.0, 2.1]), 0.5: np.array([2.06, 2.06]), 1.0: np.array([3.0, 3.0])}
    picked = choose_residual_weight(regression, tried, allowance=1.03)
    assert picked["weight"] == 0.5 and picked["validation_mm"] == pytest.approx(2.06)  # exactly at 1.03 x
    assert picked["errors_mm"] == {"0.0": 2.0, "0.25": 2.05, "0.5": 2.06, "1.0": 3.0}
    assert (
        choose_residual_weight(regression, tried, allowance=1.0)["weight"] == 0.0
    )  # nothing within: regression
    assert choose_residual_weight(regression, {0.5: np.array([1.0, 1.0])}, allowance=1.0)["weight"] == 0.5
