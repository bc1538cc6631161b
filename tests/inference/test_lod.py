"""Levels of detail in a crowd (hrr_garment.inference.lod): level 0 is the crowd itself, a change
of decoder cross-fades without a pop, a far character runs the window step every k-th frame."""

import numpy as np
import pytest

from hrr_garment.inference.lod import FADE_FRAMES, levels
from hrr_garment.motion.poses import motion_to_poses
from hrr_garment.motion.synth import synthesize


def _clip(frames: int):
    rotations, roots = motion_to_poses(synthesize("walk_curve", frames / 30.0, seed=5))
    return rotations[:frames], roots[:frames]


def test_level_zero_is_the_crowd_itself(animator):
    rotations, roots = _clip(12)
    plain, leveled = animator.crowd(mode="hybrid"), animator.crowd(mode="hybrid")
    for t in range(12):
        assert np.array_equal(
            plain.push(rotations[t : t + 1], roots[t : t + 1]),
            leveled.push(rotations[t : t + 1], roots[t : t + 1], lod=0),
        )


def test_a_change_of_decoder_fades_in_without_a_pop(animator):
    """Near (full decoder) to mid (fast) at frame 10: that frame is still the full decoder's, the
    fade's frames move toward the fast decoder's by at most ~1.5 / FADE of their difference each,
    and after the fade the character is exactly the fast decoder's."""
    frames, switch = 30, 10
    rotations, roots = _clip(frames)
    full, fast, both = (animator.crowd(mode="regression", push_out=False) for _ in range(3))
    out = {"full": [], "fast": [], "both": []}
    for t in range(frames):
        r, p = rotations[t : t + 1], roots[t : t + 1]
        out["full"].append(full.push(r, p)[0])
        out["fast"].append(fast.push(r, p, lod=1)[0])
        out["both"].append(both.push(r, p, lod=0 if t < switch else 1)[0])
    full_v, fast_v, both_v = (np.array(v) for v in (out["full"], out["fast"], out["both"]))
    assert (
        np.abs(both_v[: switch + 1] - full_v[: switch + 1]).max() < 1e-5
    )  # no jump on the frame of the change
    assert np.abs(both_v[switch + FADE_FRAMES + 1 :] - fast_v[switch + FADE_FRAMES + 1 :]).max() < 1e-5
    gap = np.abs(full_v - fast_v).max()
    assert gap > 1e-4, "the two decoders must differ for the test to mean anything"
    residual = both_v - fast_v  # the fading difference
    steps = np.linalg.norm(np.diff(residual[switch : switch + FADE_FRAMES + 2], axis=0), axis=-1).max()
    assert steps <= 1.6 / FADE_FRAMES * np.linalg.norm(full_v - fast_v, axis=-1).max() + 1e-5


def test_a_far_character_runs_the_window_step_every_kth_frame(animator, monkeypatch):
    import hrr_garment.inference.frame_path as frame_path  # the choice stage, every driver's

    calls = []
    real = frame_path.choose_windows
    monkeypatch.setattr(
        frame_path,
        "choose_windows",
        lambda bundle, windows, *a, **k: calls.append(len(windows)) or real(bundle, windows, *a, **k),
    )
    rotations, roots = _clip(9)
    crowd = animator.crowd(mode="regression")
    for t in range(9):
        out = crowd.push(
            np.repeat(rotations[t : t + 1], 2, 0),
            np.stack([roots[t], roots[t] + [2.0, 0, 0]]),
            ["near", "far"],
            lod=[0, 4],
        )
        assert np.isfinite(out).all()
    assert calls == [2, 1, 1, 1, 2, 1, 1, 1, 2]  # the far one steps on its frames 0, 4 and 8


def test_bad_levels_are_refused():
    assert levels(None, 3).tolist() == [0, 0, 0] and levels(2, 2).tolist() == [2, 2]
    for bad in ([0, -1], [0.5, 1], [0, 1, 2]):
        with pytest.raises(ValueError, match="lod"):
            levels(bad, 2)
