"""Window blending and inertialization (hrr_garment.inference.blending)."""

import numpy as np

from hrr_garment.inference.blending import Inertializer, blend_windows, window_weights
from hrr_garment.motion.windows import covering_windows


def test_blending_keeps_a_constant_and_favours_centres():
    w = window_weights(10)
    assert np.allclose(w, w[::-1]) and w.argmax() in (4, 5) and w.min() > 0
    windows = np.full((7, 10, 3, 2), 2.5, np.float32)
    assert np.allclose(blend_windows(windows, 16), 2.5)
    ramp = np.arange(16, dtype=np.float32)
    windows = np.stack([ramp[i : i + 10] for i in range(7)])[..., None]
    assert np.allclose(blend_windows(windows, 16)[:, 0], ramp)  # consistent windows blend to themselves


def test_every_frame_of_a_clip_blends_every_window_position_its_ends_too():
    """The offline windows (each frame's first and last repeated past the clip's ends) give every
    frame all W positions: a decoder whose course along a window is not flat (a bias by position)
    shifts every frame alike, the first and last frames too."""
    frames, w = 16, 10
    clip = np.arange(frames, dtype=np.float64)[:, None]
    windows = covering_windows(clip, w)
    assert windows.shape == (frames + w - 1, w, 1)
    assert (windows[0] == 0).all() and (windows[-1] == frames - 1).all()  # the ends repeated
    assert windows[w - 1, :, 0].tolist() == list(range(w))  # window i holds frames i - W + 1 .. i
    bias = (np.arange(w) / w) ** 2  # later positions of a window further off
    blended = blend_windows(windows + bias[None, :, None], frames + 2 * (w - 1))[w - 1 : w - 1 + frames]
    shift = (window_weights(w) * bias).sum() / window_weights(w).sum()
    assert np.allclose(blended - clip, shift, atol=1e-5)  # float32 out


def test_inertialization_is_continuous_in_position_and_velocity():
    inert = Inertializer(frames=6)
    out = np.array(
        [
            inert.step(np.array([0.01 * t if t < 10 else 1.0 + 0.01 * t]), ("a",) if t < 10 else ("b",))[0]
            for t in range(30)
        ]
    )
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


def test_a_continuous_part_is_followed_as_it_is_and_only_the_rest_jumps():
    """The regression under a residual is one source whatever the match: at a change of match only
    the match's departure is inertialized, and the output is the continuous part plus what an
    inertializer of the departure alone gives."""
    t = np.arange(30, dtype=np.float64)
    base = np.stack([0.05 * t, np.sin(0.3 * t)], 1)  # the regression: moving, never switching
    part = np.where(t[:, None] < 12, 0.0, 1.0) * np.array(
        [1.0, -2.0]
    )  # the departure jumps at a change of match
    sources = [("retrieval", 0 if i < 12 else 1, 0) for i in range(30)]
    split, alone = Inertializer(frames=6), Inertializer(frames=6)
    out = np.stack([split.step(base[i] + part[i], sources[i], continuous=base[i]) for i in range(30)])
    np.testing.assert_allclose(
        out - base, np.stack([alone.step(part[i], sources[i]) for i in range(30)]), atol=1e-12
    )
    assert np.abs(np.diff(out - base, axis=0)).max() <= 0.3 * 2.0  # the jump of 2 spread over frames
    # a match that changes every frame with no departure at all (a residual of weight 0): the output
    # is the regression itself, where inertializing the whole latent extrapolated it at every change
    every = [("retrieval", i, 0) for i in range(30)]
    split, whole = Inertializer(frames=6), Inertializer(frames=6)
    np.testing.assert_allclose(
        [split.step(b, s, continuous=b) for b, s in zip(base, every)], base, atol=1e-12
    )
    assert np.abs(np.stack([whole.step(b, s) for b, s in zip(base, every)]) - base).max() > 0.02


def test_a_change_between_the_whole_latent_and_its_part_does_not_jump():
    inert = Inertializer(frames=6)
    base, part = np.array([1.0, 2.0]), np.array([0.1, -0.1])
    first = inert.step(base + part, ("retrieval", 3, 0), continuous=base)
    second = inert.step(base + part, ("held", 0))  # the same latent, now whole (a held level of detail)
    np.testing.assert_allclose(second, first, atol=1e-12)


def test_paths_stepped_together_give_each_path_alone_bit_for_bit(rng):
    """A crowd steps its characters' paths in one call (Inertializer.step_rows), some of them on
    some frames only, with switches, continuous parts on some rows and a path removed and another
    added: each row's output is what its own one-path Inertializer gives, to the bit."""
    crowd, alone = Inertializer(frames=6, paths=0), {}
    rows = {name: crowd.add_path() for name in "abcd"}
    alone = {name: Inertializer(frames=6) for name in rows}
    for t in range(40):
        if t == 20:  # "b" leaves, "e" joins in its row
            crowd.remove_path(rows.pop("b"))
            rows["e"], alone["e"] = crowd.add_path(), Inertializer(frames=6)
            assert rows["e"] == 1
        names = [n for n in rows if t % 3 or n != "c"]  # "c" skips every third frame
        targets = rng.normal(size=(len(names), 3, 2))
        sources = [("clip", (t // 4 + i) % 3) for i, _ in enumerate(names)]
        split = np.array([(t + i) % 5 < 2 for i, _ in enumerate(names)])
        continuous = rng.normal(size=targets.shape)
        out = crowd.step_rows(targets, sources, continuous, split, rows=np.array([rows[n] for n in names]))
        for i, n in enumerate(names):
            one = alone[n].step(targets[i], sources[i], continuous=continuous[i] if split[i] else None)
            assert np.array_equal(out[i], one), (t, n)
    assert not np.array_equal(out, targets)  # the switches left offsets to decay
