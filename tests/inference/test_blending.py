"""Window blending and inertialization (hrr_garment.inference.blending)."""

import numpy as np

from hrr_garment.inference.blending import Inertializer, blend_windows, window_weights


def test_blending_keeps_a_constant_and_favours_centres():
    w = window_weights(10)
    assert np.allclose(w, w[::-1]) and w.argmax() in (4, 5) and w.min() > 0
    windows = np.full((7, 10, 3, 2), 2.5, np.float32)
    assert np.allclose(blend_windows(windows, 16), 2.5)
    ramp = np.arange(16, dtype=np.float32)
    windows = np.stack([ramp[i:i + 10] for i in range(7)])[..., None]
    assert np.allclose(blend_windows(windows, 16)[:, 0], ramp)  # consistent windows blend to themselves


def test_inertialization_is_continuous_in_position_and_velocity():
    inert = Inertializer(frames=6)
    out = np.array([inert.step(np.array([0.01 * t if t < 10 else 1.0 + 0.01 * t]), ("a",) if t < 10 else ("b",))[0]
                    for t in range(30)])
    step = np.diff(out)
    assert abs(step[9] - 0.01) < 0.2  # across the 1.0 jump at frame 10 most of the jump is hidden ...
    assert np.abs(np.diff(step)).max() < 6.0 / 6**2  # ... and absorbed with bounded acceleration
    assert np.abs(out[20:] - (1.0 + 0.01 * np.arange(20, 30))).max() < 0.01  # then it follows the new source
    assert np.abs(out[28:] - (1.0 + 0.01 * np.arange(28, 30))).max() < 1e-3


def test_inertialization_of_a_source_that_changes_every_frame_stays_with_the_sources(rng):
    """Causal retrieval can pick another clip for every window: the switches' offsets must decay
    together, not extrapolate the output's own velocity (which ran away, 721 mm on real clips)."""
    inert = Inertializer(frames=6)
    t = np.arange(600)
    truth = np.sin(t / 20.0)
    sources = truth + rng.normal(0.0, 0.3, len(t))  # every frame another source, 0.3 off the truth
    out = np.array([inert.step(np.array([x]), ("clip", i))[0] for i, x in enumerate(sources)])
    assert np.abs(out - truth).max() < 0.75 and np.abs(out - truth)[100:].mean() < 0.2
    assert np.abs(np.diff(out)).mean() < np.abs(np.diff(sources)).mean()  # smoother than the sources
