"""Residual retrieval: the regression plus the matched window's detail (its true latents minus the
regression of its own motion), scaled by the match's code similarity and a calibrated weight."""

import json

import numpy as np
import pytest

from hrr_garment.artifacts.residual import RESIDUAL_WEIGHTS, residual_latents
from hrr_garment.motion.synth import synthesize
from tests.conftest import current_copy, write_meta


def test_the_residual_adds_the_matchs_detail_scaled_by_its_similarity(rng):
    regression = rng.normal(size=(3, 2, 4, 2)).astype(np.float32)
    own = rng.normal(size=regression.shape).astype(np.float32)
    detail = rng.normal(size=regression.shape).astype(np.float32)
    similarity = np.array([1.0, 0.5, 0.0])
    out = residual_latents(regression, own + detail, own, similarity, 0.5)
    assert np.allclose(out[0], regression[0] + 0.5 * detail[0], atol=1e-6)
    assert np.allclose(out[1], regression[1] + 0.25 * detail[1], atol=1e-6)
    assert np.array_equal(out[2], regression[2])  # a match sharing no code group adds nothing
    # a query whose motion is the match's: at weight 1 and full similarity the result is the match
    assert np.allclose(residual_latents(own, own + detail, own, np.ones(3), 1.0), own + detail, atol=1e-6)


def test_training_calibrates_the_residual_weight_into_the_bundle(animator):
    residual = animator.bundle.meta["residual"]
    assert animator.bundle.has_residual and animator.supports("residual")
    errors = residual["errors_mm"]
    assert set(errors) == {"0.0", *map(str, RESIDUAL_WEIGHTS)} and residual["validation_mm"] == errors[str(residual["weight"])]
    allowed = [float(w) for w, e in errors.items() if e <= residual["allowance"] * errors["0.0"]]
    assert residual["weight"] == max([0.0, *allowed])


def test_residual_at_weight_zero_is_the_regression_and_otherwise_adds_the_matches(animator, monkeypatch):
    from hrr_garment.artifacts.residual import match_regression
    from hrr_garment.models.codes import encode_motion
    from hrr_garment.motion.windows import sequence_windows

    bundle = animator.bundle
    motion = synthesize("walk", 1.0, seed=3)
    monkeypatch.setitem(bundle.meta, "residual", {"weight": 0.0})
    regression = animator.animate(motion, mode="regression", collision=False)
    zero = animator.animate(motion, mode="residual", collision=False)
    assert np.allclose(zero.vertices, regression.vertices, atol=1e-6)
    assert not zero.retrieved.any() and (zero.match >= 0).all()  # regression plus a match, not a retrieval
    # at weight 1, each window's latents move by its match's residual times the similarity
    monkeypatch.setitem(bundle.meta, "residual", {"weight": 1.0})
    from hrr_garment.inference.gate import choose_windows

    windows = np.ascontiguousarray(sequence_windows(animator.features(motion), animator.window))
    chosen = choose_windows(bundle, windows, animator.resolve(mode="residual"))
    enc = encode_motion(bundle.codespace, bundle.motion_stats, bundle.latent_stats, windows)
    match, similarity = bundle.database.search(enc.codes)
    own = match_regression(bundle.codespace, bundle.motion_stats, bundle.latent_stats, bundle.database, match)
    expected = enc.regression + similarity[:, None, None, None] * (bundle.database.latents[match] - own)
    assert np.allclose(chosen.latents, expected, atol=1e-5)
    assert not np.allclose(chosen.latents, enc.regression, atol=1e-3)  # the detail is there
    assert np.array_equal(chosen.match[:, 0], bundle.database.sequence[match])
    assert not chosen.retrieved.any() and chosen.follows_match.all()  # a change of match is a change of source


def test_stream_in_the_residual_mode_equals_offline_causal(animator, monkeypatch):
    monkeypatch.setitem(animator.bundle.meta, "residual", {"weight": 0.5})
    motion = synthesize("walk_curve", 1.0, seed=5)
    causal = animator.animate(motion, mode="residual", causal=True)
    stream = animator.stream(mode="residual")
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal.vertices).max() <= 1e-5


def test_a_bundle_before_the_residual_mode_says_how_to_calibrate_it_and_hrr_train_does(trained, tmp_path, capsys):
    from hrr_garment.artifacts.bundle import BundleError, load_bundle
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.inference.animator import Animator

    old, stage = current_copy(trained, tmp_path / "model")
    meta = json.loads((old / "bundle.json").read_text())
    calibrated = meta.pop("residual")
    write_meta(old, meta)
    animator = Animator.load(old)
    assert not animator.supports("residual") and animator.supports("hybrid")
    with pytest.raises(BundleError, match="hrr-train --stage codespace"):
        animator.animate(synthesize("walk", 0.5, seed=1), mode="residual")
    # the finished stage is reused (nothing retrained) and only the weight is calibrated
    weights = (old / "motion_encoder.safetensors").read_bytes()
    capsys.readouterr()
    assert train_main(stage) == 0
    assert "(reused)" in capsys.readouterr().out and (old / "motion_encoder.safetensors").read_bytes() == weights
    again = load_bundle(old).meta["residual"]
    assert again["weight"] == calibrated["weight"] and again["errors_mm"] == pytest.approx(calibrated["errors_mm"])
    meta["residual"] = {"weight": -1}
    write_meta(old, meta)
    with pytest.raises(BundleError, match="'residual' must hold a finite 'weight'"):
        load_bundle(old)
