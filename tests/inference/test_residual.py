"""Residual retrieval: the regression plus the matched window's detail (its true latents minus the
regression of its own motion), scaled by the match's code similarity and a calibrated weight."""

import json
from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.artifacts.manifest_entries import ResidualEntry
from hrr_garment.artifacts.residual import RESIDUAL_WEIGHTS, residual_latents
from hrr_garment.motion.synth import synthesize
from tests.conftest import current_copy, with_manifest, write_meta


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
    residual = animator.bundle.manifest.residual
    assert animator.bundle.has_residual and animator.supports("residual")
    errors = residual.errors_mm
    assert (
        set(errors) == {"0.0", *map(str, RESIDUAL_WEIGHTS)}
        and residual.validation_mm == errors[str(residual.weight)]
    )
    allowed = [float(w) for w, e in errors.items() if e <= residual.allowance * errors["0.0"]]
    assert residual.weight == max([0.0, *allowed])


def test_residual_at_weight_zero_is_the_regression_and_otherwise_adds_the_matches(animator, monkeypatch):
    from hrr_garment.artifacts.residual import match_regression
    from hrr_garment.models.codes import encode_motion
    from hrr_garment.motion.windows import sequence_windows

    bundle = animator.bundle
    motion = synthesize("walk", 1.0, seed=3)
    with_manifest(monkeypatch, bundle, residual=ResidualEntry(weight=0.0))
    regression = animator.animate(motion, mode="regression", push_out=False)
    zero = animator.animate(motion, mode="residual", push_out=False)
    assert np.allclose(zero.vertices, regression.vertices, atol=1e-6)
    assert not zero.retrieved.any() and (zero.match >= 0).all()  # regression plus a match, not a retrieval
    # at weight 1, each window's latents move by its match's residual times the similarity
    with_manifest(monkeypatch, bundle, residual=ResidualEntry(weight=1.0))
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
    assert (
        not chosen.retrieved.any() and chosen.follows_match.all()
    )  # a change of match is a change of source


def test_the_detail_mode_on_the_residual_inertializes_its_latents_as_the_residual_mode(animator, monkeypatch):
    """Its latents are the residual mode's, changing with the match: a causal path must smooth
    each change of match as the residual mode does (they once went through raw: jumps every frame)."""
    from hrr_garment.inference.blending import causal_latents
    from hrr_garment.inference.gate import choose_windows
    from hrr_garment.inference.run_settings import DetailLook
    from hrr_garment.motion.windows import causal_windows

    with_manifest(monkeypatch, animator.bundle, residual=ResidualEntry(weight=1.0))
    motion = synthesize("walk_curve", 1.5, seed=5)
    windows = causal_windows(animator.features(motion, causal=True), animator.window)
    chosen = {
        mode: choose_windows(
            animator.bundle, windows, animator.resolve(mode=mode, detail=look), last_frame=True
        )
        for mode, look in (("residual", DetailLook()), ("detail", DetailLook("residual", 1.0)))
    }
    assert np.array_equal(chosen["detail"].latents, chosen["residual"].latents)
    assert len(np.unique(chosen["detail"].match, axis=0)) > 1  # the match changes along the clip
    assert chosen["detail"].follows_match.all()
    np.testing.assert_array_equal(
        causal_latents(chosen["detail"], animator.blend), causal_latents(chosen["residual"], animator.blend)
    )
    regression = choose_windows(
        animator.bundle,
        windows,
        animator.resolve(mode="detail", detail=DetailLook("regression", 1.0)),
        last_frame=True,
    )
    assert not regression.follows_match.any()  # on the regression: one continuous source


def test_stream_in_the_residual_mode_equals_offline_causal(animator, monkeypatch):
    with_manifest(monkeypatch, animator.bundle, residual=ResidualEntry(weight=0.5))
    motion = synthesize("walk_curve", 1.0, seed=5)
    causal = animator.animate(motion, mode="residual", causal=True)
    stream = animator.stream(mode="residual")
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal.vertices).max() <= 1e-5


def test_a_bundle_before_the_residual_mode_says_how_to_calibrate_it_and_hrr_train_does(
    trained, tmp_path, capsys
):
    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle
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
    assert (
        "(reused)" in capsys.readouterr().out and (old / "motion_encoder.safetensors").read_bytes() == weights
    )
    again = load_bundle(old).manifest.residual
    assert again.weight == calibrated["weight"] and dict(again.errors_mm) == pytest.approx(
        calibrated["errors_mm"]
    )
    meta["residual"] = {"weight": -1}
    write_meta(old, meta)
    with pytest.raises(BundleError, match="'residual' must hold a finite 'weight'"):
        load_bundle(old)


def test_free_cloth_weights_ramp_from_the_body_and_scale_the_residual_per_node(rng):
    from hrr_garment.artifacts.free_cloth import free_cloth_weights

    hang = np.array([-0.003, 0.012, 0.025, 0.040, 0.300])
    assert free_cloth_weights(hang, (10, 40)) == pytest.approx([0.0, 2 / 30, 0.5, 1.0, 1.0], abs=1e-6)
    with pytest.raises(ValueError, match="lo < hi"):
        free_cloth_weights(hang, (40, 10))
    regression = rng.normal(size=(2, 3, 5, 2)).astype(np.float32)
    own, detail = (rng.normal(size=regression.shape).astype(np.float32) for _ in range(2))
    nodes = free_cloth_weights(hang, (10, 40))
    out = residual_latents(regression, own + detail, own, np.ones(2), 0.5, nodes=nodes)
    assert np.allclose(out, regression + 0.5 * nodes[None, None, :, None] * detail, atol=1e-6)
    assert np.array_equal(
        residual_latents(regression, own + detail, own, np.ones(2), 0.5, nodes=np.zeros(5)), regression
    )
    assert np.allclose(
        residual_latents(regression, own + detail, own, np.ones(2), 0.5, nodes=np.ones(5)),
        residual_latents(regression, own + detail, own, np.ones(2), 0.5),
        atol=1e-6,
    )


def test_the_residual_on_free_cloth_keeps_the_regression_where_the_cloth_lies_on_the_body(
    animator, monkeypatch
):
    """With the calibrated ramp, nodes on the body take no residual, free ones all of it, in every path."""
    from hrr_garment.body.capsules import capsule_signed_distance
    from hrr_garment.inference.gate import choose_windows
    from hrr_garment.motion.windows import sequence_windows

    bundle = animator.bundle
    hang = bundle.node_hang_m
    node_vertices = bundle.autoencoder.hierarchy.node_vertices()
    assert hang.shape == (bundle.autoencoder.hierarchy.sizes[-1],) and len(
        set(node_vertices.tolist())
    ) == len(hang)
    a, b = bundle.made_for.rest_pose()  # the node's own centre vertex, at rest, against the body
    assert hang[0] == pytest.approx(
        capsule_signed_distance(
            bundle.template.vertices[node_vertices[:1]].astype(np.float64), a, b, radii=bundle.made_for.radii
        )[0][0],
        abs=1e-6,
    )
    lo, hi = np.quantile(hang, [0.3, 0.7]) * 1000  # a ramp through the middle of this garment's hang
    with_manifest(monkeypatch, bundle, residual=ResidualEntry(weight=1.0))
    windows = np.ascontiguousarray(
        sequence_windows(animator.features(synthesize("walk", 1.0, seed=3)), animator.window)
    )
    plain = choose_windows(bundle, windows, animator.resolve(mode="residual")).latents
    regression = choose_windows(bundle, windows, animator.resolve(mode="regression")).latents
    with_manifest(monkeypatch, bundle, auto=replace(bundle.auto, residual_free_mm=(float(lo), float(hi))))
    nodes = bundle.residual_nodes
    assert (nodes == 0).any() and (nodes == 1).any()
    free = choose_windows(bundle, windows, animator.resolve(mode="residual")).latents
    assert np.allclose(free[:, :, nodes == 0], regression[:, :, nodes == 0], atol=1e-6)
    assert np.allclose(free[:, :, nodes == 1], plain[:, :, nodes == 1], atol=1e-6)
    motion = synthesize("walk_curve", 1.0, seed=5)  # the stream takes it as offline causal does
    causal = animator.animate(motion, mode="residual", causal=True)
    stream = animator.stream(mode="residual")
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal.vertices).max() <= 1e-5


def test_a_free_cloth_ramp_in_bundle_json_is_checked(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle

    root, _, _ = trained
    shutil.copytree(root / "model", tmp_path / "model")
    meta = json.loads((tmp_path / "model" / "bundle.json").read_text())
    write_meta(tmp_path / "model", {**meta, "auto": {**meta["auto"], "residual_free_mm": [40, 10]}})
    with pytest.raises(BundleError, match="residual_free_mm"):
        load_bundle(tmp_path / "model")
