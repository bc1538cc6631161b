"""The cloth settling after a stop (inference/settle.py): the lag's known answers, its fading after
the stop, what it leaves alone, and the same recursion offline, in a stream and in a crowd."""

from types import SimpleNamespace

import numpy as np
import pytest

from hrr_garment.inference.settle import FADE, SettleLag, settle_crowd
from hrr_garment.motion.compose import held_still
from hrr_garment.motion.features import causal_features, motion_features
from hrr_garment.motion.memory import LONG_STILL_S, moving_fraction, still_clock
from hrr_garment.motion.synth import synthesize

FPS = 30.0


def _walk_then_stand(stand_s: float = 8.0, seed: int = 3):
    return held_still(synthesize("walk_curve", 1.5, seed=seed), round(stand_s * FPS))


def test_right_after_a_stop_the_output_closes_on_the_prediction_at_the_time_constant():
    """The prediction jumps at the stop and holds: the gap closes as exp(-t / s_t), s_t the time
    constant fading over FADE of them; while the body moved, the output was the prediction."""
    motion = _walk_then_stand()
    features = causal_features(motion)
    lag = SettleLag(1.0, FPS)
    tau = still_clock(features, FPS)
    stop = int(np.flatnonzero(tau == 0.0)[-1])  # the clock's last reset: the last moving frame
    latents = np.zeros((motion.num_frames, 2, 3), np.float32)
    latents[stop + 1 :] = 1.0  # the prediction steps at the stop
    out = lag.apply(latents, features)
    np.testing.assert_array_equal(out[: stop + 1], latents[: stop + 1])
    # by hand: each frame keeps its still share times exp(-1 / (fps s_t)) of the gap
    gap, expected = 1.0, []
    for t in range(stop + 1, motion.num_frames):
        s_t = max(0.0, 1.0 - tau[t] / (FADE * 1.0))
        gap *= (
            np.exp(-1.0 / (FPS * s_t)) * (1.0 - moving_fraction(features[t : t + 1])[0]) if s_t > 0 else 0.0
        )
        expected.append(1.0 - gap)
    np.testing.assert_allclose(out[stop + 1 :, 0, 0], expected, atol=1e-5)
    assert 0.3 < out[stop + round(FPS), 0, 0] < 0.8  # a second after the stop: on its way
    assert out[stop + round(FADE * FPS) + 1, 0, 0] == pytest.approx(1.0)  # faded out: as predicted


def test_a_body_that_stood_from_the_start_is_not_lagged():
    """A wave on the spot: its cloth moves with the gestures the model predicts, no stop to settle."""
    standing = held_still(synthesize("walk", 1.0, seed=0).slice(0, 1), 90)
    features = motion_features(standing)
    assert still_clock(features, FPS).min() == LONG_STILL_S
    latents = np.random.default_rng(0).normal(size=(90, 2, 3)).astype(np.float32)
    np.testing.assert_array_equal(SettleLag(2.0, FPS).apply(latents, features), latents)


def test_a_crowds_steps_equal_each_clip_lagged_whole():
    """Characters that join later start from their own first frame, their clocks their own."""
    clips = [_walk_then_stand(5.0, seed) for seed in (1, 2, 3)]
    features = [causal_features(m) for m in clips]
    rng = np.random.default_rng(0)
    latents = [rng.normal(size=(len(f), 4, 3)).astype(np.float32) for f in features]
    joins, length = [0, 5, 12], min(len(f) for f in features) - 12
    lag = SettleLag(1.5, FPS)
    whole = [lag.apply(z, f) for z, f in zip(latents, features)]
    chars = [SimpleNamespace(settled=None) for _ in range(3)]
    for frame in range(length + 12):
        rows = [i for i in range(3) if joins[i] <= frame < joins[i] + length]
        out = settle_crowd(
            lag,
            [chars[i] for i in rows],
            np.stack([latents[i][frame - joins[i]] for i in rows]),
            features=np.stack([features[i][frame - joins[i]] for i in rows]),
        )
        for j, i in enumerate(rows):
            np.testing.assert_allclose(out[j], whole[i][frame - joins[i]], atol=1e-6)


@pytest.mark.parametrize("mode", ["regression", "detail"])
def test_the_lag_streams_as_it_animates_causally(animator, mode):
    """A walk that stops: the lag changes the cloth only once the body stops, and a stream lags it
    frame for frame as the causal clip does."""
    motion = _walk_then_stand(3.0)
    plain = animator.animate(motion, mode=mode, causal=True)
    lagged = animator.animate(motion, mode=mode, causal=True, settle=1.0)
    assert lagged.settings["settle"] == 1.0 and plain.settings["settle"] == 0.0
    stop = int(np.flatnonzero(still_clock(causal_features(motion), FPS) == 0.0)[-1])
    np.testing.assert_array_equal(lagged.vertices[: stop + 1], plain.vertices[: stop + 1])
    assert np.abs(lagged.vertices[stop + 5 : stop + 30] - plain.vertices[stop + 5 : stop + 30]).max() > 1e-4
    stream = animator.stream(mode=mode, settle=1.0)
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - lagged.vertices).max() <= 1e-5


@pytest.mark.parametrize(
    ("field", "bad"),
    [("settle", bad) for bad in (-1.0, 25.0, float("nan"), "long", True, None)]
    + [("swing", bad) for bad in (0.0, -1.0, 3.5, float("nan"), "big", True)],
)
def test_a_look_out_of_range_is_refused(field, bad):
    """The settling lag and the swing's gain (inference/swing.py) alike."""
    from hrr_garment.inference.run_settings import RunSettings

    with pytest.raises((ValueError, TypeError), match=field):
        RunSettings(**{field: bad})


def test_the_torch_step_and_device_crowd_refuse_a_swing_gain(animator):
    from hrr_garment.inference.frame_path import FramePath
    from hrr_garment.inference.torch_crowd import DeviceCrowd
    from hrr_garment.inference.torch_step import stream_step

    with pytest.raises(ValueError, match="swing"):
        DeviceCrowd(animator, animator.resolve(mode="regression", device="cpu", swing=1.2))
    with pytest.raises(ValueError, match="swing"):
        stream_step(FramePath(animator, animator.resolve(mode="regression", swing=1.2)))


def test_the_device_crowd_lags_as_the_native_crowd_does(animator):
    """The torch step's lag (inference/torch_settle.py; a GPU's path, run on the CPU): two
    characters, one joining later, walking and then stopping, as the native crowd gives them."""
    from hrr_garment.motion.poses import motion_to_poses

    poses = [motion_to_poses(_walk_then_stand(2.0, seed)) for seed in (1, 2)]
    native, device = (animator.crowd(mode="regression", settle=1.0, device=d) for d in ("native", "cpu"))
    plain = animator.crowd(mode="regression", device="native")
    worst, lagged = 0.0, 0.0
    for t in range(len(poses[1][0]) - 5):
        keys = ["a", "b"] if t >= 5 else ["a"]
        rotations = np.stack([poses[i][0][t - 5 * i] for i in range(len(keys))])
        roots = np.stack([poses[i][1][t - 5 * i] + [2.0 * i, 0, 0] for i in range(len(keys))])
        theirs = native.push(rotations, roots, keys)
        worst = max(worst, float(np.abs(device.push(rotations, roots, keys) - theirs).max()))
        lagged = max(lagged, float(np.abs(theirs - plain.push(rotations, roots, keys)).max()))
    assert worst < 1e-4, f"{worst * 1000:.3f} mm from the native crowd"
    assert lagged > 1e-3  # the lag acted


def test_offline_the_lag_changes_the_cloth_only_after_the_stop(animator):
    motion = _walk_then_stand(3.0)
    plain, lagged = (animator.animate(motion, mode="regression", settle=s) for s in (0.0, 1.0))
    stop = int(np.flatnonzero(still_clock(motion_features(motion), FPS) == 0.0)[-1])
    np.testing.assert_array_equal(lagged.vertices[: stop + 1], plain.vertices[: stop + 1])
    assert np.abs(lagged.vertices[stop + 5 : stop + 30] - plain.vertices[stop + 5 : stop + 30]).max() > 1e-4


def test_a_crowd_with_a_swing_gain_stays_native_where_a_gpu_would_run_the_regression(animator, monkeypatch):
    from hrr_garment.inference.stream import CrowdStream

    monkeypatch.setattr("torch.cuda.is_available", lambda: True)
    assert isinstance(animator.crowd(mode="regression", swing=1.2), CrowdStream)


@pytest.mark.parametrize(
    ("field", "value", "bad", "printed"),
    [("settle", 1.5, "-1", "settling over 1.5 s"), ("swing", 1.4, "0", "mode regression, swing x1.4")],
)
def test_hrr_animate_takes_a_look_and_refuses_a_bad_one(
    trained, tmp_path, capsys, field, value, bad, printed
):  # noqa: PLR0913
    """--settle and --swing: the cloth written is the API's with the look, recorded in out.h5; a bad
    value is refused naming the flag, and no file is written."""
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.io import save_motion

    root, _, _ = trained
    motion = _walk_then_stand(2.0, seed=4)
    clip = tmp_path / "stop.npz"
    save_motion(motion, clip)
    out = tmp_path / "out.h5"
    model = ["--model", str(root / "model")]
    asked = ["--mode", "regression", f"--{field}", str(value), "--no-collision"]
    assert animate_main([str(clip), "-o", str(out), *model, *asked]) == 0
    assert printed in capsys.readouterr().out
    written = read_animation_h5(out)
    assert written.attrs[field] == value
    look = {field: value}
    expected = Animator.load(root / "model").animate(motion, mode="regression", push_out=False, **look)
    np.testing.assert_array_equal(written.vertices, expected.vertices)
    refused = tmp_path / "refused.h5"
    assert animate_main([str(clip), "-o", str(refused), *model, f"--{field}", bad]) == 2
    assert f"--{field}" in capsys.readouterr().err and not refused.exists()


def test_the_device_crowds_draw_lags_as_the_native_crowds_does(animator):
    """The sample mode with the lag on a torch device: the lag's state before the draw's (the
    step's order), each seed's cloth as the native crowd draws and lags it."""
    from hrr_garment.motion.poses import motion_to_poses
    from tests.conftest import with_drawn_sampler

    drawing = with_drawn_sampler(animator)
    rotations, roots = motion_to_poses(_walk_then_stand(2.0, seed=1))
    crowds = [drawing.crowd(mode="sample", seed=5, settle=1.0, device=d) for d in ("native", "cpu")]
    worst = 0.0
    for t in range(len(rotations)):
        native, device = (
            c.push(rotations[[t, t]], roots[[t, t]] + [[0, 0, 0], [2, 0, 0]], ["a", "b"]) for c in crowds
        )
        worst = max(worst, float(np.abs(native - device).max()))
    assert worst < 1e-4, f"{worst * 1000:.3f} mm from the native crowd"
