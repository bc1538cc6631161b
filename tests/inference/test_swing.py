"""The free cloth's swing restored (inference/swing.py): what the gain scales and what it leaves,
the same recursion offline, in a stream and in a crowd, and where the calibrated gain runs."""

from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.inference.swing import FREE_CLOTH_MM, HALF_LIFE_S, SwingGain
from hrr_garment.motion.synth import synthesize
from tests.conftest import with_manifest

LO, HI = (x / 1000.0 for x in FREE_CLOTH_MM)
HANG = np.array(
    [0.0, 0.012, (LO + HI) / 2, HI + 0.05], np.float32
)  # on the body, the bodice's clearance, the ramp's middle, free


def test_the_gain_scales_the_departure_on_free_cloth_only():
    gain = SwingGain.of(1.5, HANG, fps=30.0)
    assert gain.gains.tolist() == pytest.approx([1.0, 1.0, 1.25, 1.5])
    assert gain.decay == pytest.approx(0.5 ** (1.0 / (30.0 * HALF_LIFE_S)))
    t = np.arange(600)
    rest = np.array([0.1, -0.2, 0.3, 0.4])
    swing = 0.05 * np.sin(
        2 * np.pi * t / 30.0
    )  # a 1 s swing about a fixed rest: the moving average keeps the rest
    latents = (rest[None, :, None] + swing[:, None, None] * np.ones((1, 4, 2))).astype(np.float32)
    out = gain.apply(latents)
    late = slice(300, None)  # once the average has settled on the rest
    amplitude = np.abs(out[late] - rest[None, :, None]).max(axis=(0, 2)) / np.abs(swing[late]).max()
    assert amplitude[:2] == pytest.approx([1.0, 1.0], abs=1e-5)  # the bodice as predicted
    assert amplitude[2] == pytest.approx(1.25, rel=0.03) and amplitude[3] == pytest.approx(1.5, rel=0.03)
    still = np.repeat(latents[:1], 50, axis=0)  # cloth that does not move stays where it is
    np.testing.assert_allclose(gain.apply(still), still, atol=1e-6)
    np.testing.assert_allclose(SwingGain.of(1.0, HANG, fps=30.0).apply(latents), latents, atol=1e-6)


def test_a_crowds_steps_equal_each_clip_applied_whole():
    """Characters that join later start their own average on their first frame."""
    rng = np.random.default_rng(0)
    clips = [rng.normal(size=(40, 4, 3)).astype(np.float32) for _ in range(3)]
    joins = [0, 5, 12]
    gain = SwingGain.of(1.3, HANG, fps=30.0)
    whole = [gain.apply(c) for c in clips]
    means = np.zeros((3, 4, 3))
    started = np.zeros(3, bool)
    for frame in range(40):
        rows = [i for i in range(3) if joins[i] <= frame < joins[i] + 28]  # each streams 28 frames
        latent = np.stack([clips[i][frame - joins[i]] for i in rows])
        out, new = gain.step(latent, latent, means[rows], ~started[rows])
        means[rows], started[rows] = new, True
        for j, i in enumerate(rows):
            np.testing.assert_array_equal(out[j], whole[i][frame - joins[i]])


def test_only_the_regressions_departure_is_scaled():
    """What a mode adds to the regression (a match's simulated departure) passes as it is."""
    rng = np.random.default_rng(1)
    regression = rng.normal(size=(60, 4, 3)).astype(np.float32)
    added = rng.normal(size=(60, 4, 3)).astype(np.float32)
    gain = SwingGain.of(1.5, HANG, fps=30.0)
    np.testing.assert_allclose(
        gain.apply(regression + added, regression), gain.apply(regression) + added, atol=1e-5
    )


@pytest.mark.parametrize("mode", ["regression", "residual", "detail"])
def test_swing_streams_as_it_animates_offline(animator, mode, monkeypatch):
    from hrr_garment.inference.run_settings import DetailLook

    bundle = animator.bundle
    with_manifest(monkeypatch, bundle, residual=replace(bundle.manifest.residual, weight=0.5))
    look = {"detail": DetailLook("residual", 1.0)} if mode == "detail" else {}
    motion = synthesize("walk_curve", 1.0, seed=3)
    plain = animator.animate(motion, mode=mode, causal=True, **look)
    swung = animator.animate(motion, mode=mode, causal=True, swing=1.4, **look)
    assert swung.settings["swing"] == 1.4 and plain.settings["swing"] == 1.0
    assert np.abs(swung.vertices - plain.vertices).max() > 1e-4  # it changes the cloth
    stream = animator.stream(mode=mode, swing=1.4, **look)
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - swung.vertices).max() <= 1e-5
    offline = animator.animate(
        motion, mode=mode, swing=1.4, **look
    )  # offline too, from the blended regression
    assert np.abs(offline.vertices - animator.animate(motion, mode=mode, **look).vertices).max() > 1e-4


def test_the_calibrated_gain_runs_in_auto_only(animator, monkeypatch):
    auto = animator.bundle.auto
    with_manifest(monkeypatch, animator.bundle, auto=replace(auto, swing_gain=1.2))
    assert animator.resolve().swing == 1.2
    assert animator.resolve(mode="regression").swing == 1.0  # a mode named runs as predicted
    assert animator.resolve(mode="regression", swing=1.1).swing == 1.1
    with_manifest(monkeypatch, animator.bundle, auto=replace(auto, swing_gain=None))
    assert animator.resolve().swing == 1.0  # calibrated before the gain: as it animated then


def test_an_evaluation_records_the_gain_each_mode_ran_with(animator, trained, monkeypatch):
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval.evaluate import EvaluationSettings, evaluate_modes

    _, data, _ = trained
    ds = GarmentDataset(data)
    records = [ds.sequence(ds.splits["val"][0])]
    with_manifest(monkeypatch, animator.bundle, auto=replace(animator.bundle.auto, swing_gain=1.2))
    results = evaluate_modes(animator, records, EvaluationSettings(("auto", "regression"), progress=False))
    assert results["auto"].to_dict()["swing"] == 1.2 and results["regression"].to_dict()["swing"] == 1.0
