"""Clips of hours load and turn into features in passes (issue 48, reproducer 4): the passes give
the one-pass result exactly, and the memory they need does not grow with the clip."""

import tracemalloc

import numpy as np
import pytest

from hrr_garment.motion import resample
from hrr_garment.motion.features import motion_features
from hrr_garment.motion.io import load_motion, save_amass, save_motion
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.synth import synthesize


def long_motion(frames: int) -> Motion:
    dance = synthesize("dance", 4.0, seed=1)
    reps = frames // dance.num_frames + 1
    return Motion(
        np.tile(dance.local_rotations, (reps, 1, 1, 1))[:frames],
        np.tile(dance.root_translation, (reps, 1))[:frames],
        dance.fps,
    )


@pytest.fixture
def clip() -> Motion:
    return long_motion(500)


def one_pass_and_in_passes(monkeypatch, compute):
    """``compute()`` with passes longer than any clip here, then in passes of 7 frames."""
    monkeypatch.setattr(resample, "FRAME_CHUNK", 10**9)
    whole = compute()
    monkeypatch.setattr(resample, "FRAME_CHUNK", 7)
    return whole, compute()


def test_features_in_passes_equal_one_pass(monkeypatch, clip):
    whole, passes = one_pass_and_in_passes(
        monkeypatch, lambda: motion_features(Motion(clip.local_rotations, clip.root_translation, clip.fps))
    )
    assert passes.shape == whole.shape == (500, 124)
    np.testing.assert_array_equal(passes, whole)


@pytest.mark.parametrize("width", [1.0, 4.0])  # interpolated, and low-pass filtered (120 -> 30 fps)
def test_resampling_in_passes_equals_one_pass(monkeypatch, clip, width):
    frames = resample.resample_times(clip.num_frames, 120.0, 30.0)
    rot = clip.local_rotations.astype(np.float64)
    whole, passes = one_pass_and_in_passes(
        monkeypatch, lambda: resample.resample_rotations(rot, frames, width)
    )
    np.testing.assert_array_equal(passes, whole)
    assert passes.dtype == np.float64 and len(passes) == len(frames)
    root = clip.root_translation
    whole, passes = one_pass_and_in_passes(monkeypatch, lambda: resample.resample_linear(root, frames, width))
    np.testing.assert_array_equal(passes, whole)


@pytest.mark.parametrize("fmt", ["native", "amass"])
def test_loading_in_passes_equals_one_pass(monkeypatch, clip, tmp_path, fmt):
    path = tmp_path / f"{fmt}.npz"
    (save_motion if fmt == "native" else save_amass)(clip, path)
    whole, passes = one_pass_and_in_passes(monkeypatch, lambda: load_motion(path))
    np.testing.assert_array_equal(passes.local_rotations, whole.local_rotations)
    np.testing.assert_array_equal(passes.root_translation, whole.root_translation)


def peak_bytes(compute) -> int:
    tracemalloc.start()
    try:
        compute()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_for_features_does_not_grow_with_the_clip(monkeypatch):
    """The features of 12,000 frames in passes of 1,024 need under a third of what one pass
    does: the float64 temporaries are a pass's, and only the float32 result is the clip's."""
    motion = long_motion(12_000)
    monkeypatch.setattr(resample, "FRAME_CHUNK", 1024)
    in_passes = peak_bytes(
        lambda: motion_features(Motion(motion.local_rotations, motion.root_translation, motion.fps))
    )
    monkeypatch.setattr(resample, "FRAME_CHUNK", 10**9)
    one_pass = peak_bytes(
        lambda: motion_features(Motion(motion.local_rotations, motion.root_translation, motion.fps))
    )
    result = 12_000 * 124 * 4
    assert in_passes < one_pass / 3
    assert in_passes < 5 * result


@pytest.mark.parametrize("fmt", ["native", "amass"])
def test_memory_for_loading_does_not_grow_past_the_file(monkeypatch, tmp_path, fmt):
    """Loading 12,000 frames in passes needs a third of what one pass does and under four times
    the file: no float64 copy of the whole clip's rotations (one alone would be 19 MB)."""
    motion = long_motion(12_000)
    path = tmp_path / f"{fmt}.npz"
    (save_motion if fmt == "native" else save_amass)(motion, path)
    monkeypatch.setattr(resample, "FRAME_CHUNK", 1024)
    in_passes = peak_bytes(lambda: load_motion(path))
    monkeypatch.setattr(resample, "FRAME_CHUNK", 10**9)
    one_pass = peak_bytes(lambda: load_motion(path))
    assert in_passes < one_pass / 3
    assert in_passes < 4 * path.stat().st_size
