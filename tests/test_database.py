"""The retrieval database keeps each frame once (hrr_garment.artifacts.database.WindowFrames):
reading windows from frames gives the windows themselves, every search and distance is unchanged,
a bundle stores the frames, and bundles that stored every window still load."""

import importlib.util
import shutil
from pathlib import Path

import numpy as np
import pytest
from safetensors.numpy import load_file

from hrr_garment.artifacts.bundle import add_bundle_part, load_bundle
from hrr_garment.artifacts.database import CodeDatabase, WindowFrames
from hrr_garment.data.windows import build_windows
from hrr_garment.train.codespace import window_frames

WINDOW = 4


def sequences(seed: int = 0) -> tuple[dict, dict, list[str]]:
    """Motion (T, 5) and latents (T, 3, 2) of three sequences, one shorter than a window."""
    rng = np.random.default_rng(seed)
    names = ["a", "short", "b"]
    lengths = {"a": 9, "short": 3, "b": 7}
    motion = {n: rng.normal(size=(lengths[n], 5)).astype(np.float32) for n in names}
    latents = {n: rng.normal(size=(lengths[n], 3, 2)).astype(np.float32) for n in names}
    return motion, latents, names


def test_frames_read_as_the_windows_they_hold():
    motion, latents, names = sequences()
    w = build_windows(motion, latents, names, WINDOW)
    frames = window_frames(latents, w)
    assert len(frames) == len(w) == 6 + 4 and frames.shape == w.latents.shape
    assert len(frames.frames) == 9 + 3 + 7  # each frame once
    rows = np.array([7, 0, 7, 3])
    assert np.array_equal(frames[rows], w.latents[rows])
    assert np.array_equal(frames[rows, -1:], w.latents[rows, -1:])
    assert np.array_equal(frames[5], w.latents[5]) and np.array_equal(frames[w.sequence == 2], w.latents[w.sequence == 2])
    assert np.array_equal(frames.windows(), w.latents)
    with pytest.raises(ValueError, match="run past the 19 frames"):
        WindowFrames(frames.frames, np.array([0, 16]), WINDOW)


def test_a_database_of_frames_answers_as_the_one_of_windows_and_stores_them_once():
    motion, latents, names = sequences(1)
    w = build_windows(motion, latents, names, WINDOW)
    codes = np.random.default_rng(2).integers(0, 4, (len(w), 6))
    whole = CodeDatabase(codes, w.latents, w.sequence, w.start, names, 4, w.motion)
    framed = CodeDatabase(codes, window_frames(latents, w), w.sequence, w.start, names, 4, window_frames(motion, w))
    query = w.motion[[1, 8, 4]] + 0.01
    assert np.array_equal(framed.nearest_motion(query), whole.nearest_motion(query))
    assert np.array_equal(framed.nearest_motion(query, np.array([0, 2, -1])), whole.nearest_motion(query, np.array([0, 2, -1])))
    batch = framed.nearest_motion(query)
    assert [int(framed.nearest_motion(q[None])[0]) for q in query] == batch.tolist()  # alone = in a batch
    twins = CodeDatabase(codes[:4], w.latents[:4], np.zeros(4, np.int32), np.arange(4), names, 4, w.motion[[2, 1, 2, 3]])
    assert twins.nearest_motion(w.motion[[2]])[0] == 0  # an exact tie goes to the lowest row
    rows = np.array([2, 9, 0])
    np.testing.assert_allclose(framed.motion_distance(query, rows), whole.motion_distance(query, rows), rtol=1e-6)
    stored = framed.arrays()
    assert "latents" not in stored and "motion" not in stored
    assert stored["latent_frames"].size * WINDOW > w.latents.size  # fewer values than the windows ...
    assert stored["latent_frames"].size < w.latents.size  # ... by about the window's length
    again = CodeDatabase.from_arrays(stored, names, 4, WINDOW)
    assert np.array_equal(again.latents[np.arange(len(w))], w.latents) and np.array_equal(again.motion.windows(), w.motion)
    old = CodeDatabase.from_arrays(whole.arrays(), names, 4, WINDOW)  # the windows themselves, as bundles stored them
    assert np.array_equal(old.latents, w.latents)
    back = WindowFrames.of_windows(w.latents, w.sequence, w.start)  # the windows back into frames
    assert np.array_equal(back.windows(), w.latents) and len(back.frames) == 9 + 7  # the short sequence has no window
    bad = w.latents.copy()
    bad[1, 0] += 1.0  # window 1's first frame is window 0's second
    with pytest.raises(ValueError, match="not stride-1 crops"):
        WindowFrames.of_windows(bad, w.sequence, w.start)
    with pytest.raises(ValueError, match="without the windows' first frames"):
        CodeDatabase.from_arrays({k: v for k, v in stored.items() if k != "first"}, names, 4, WINDOW)


def test_a_trained_bundle_stores_frames_and_one_that_stored_windows_still_loads(trained, tmp_path):
    root, _, _ = trained
    stored = load_file(str(root / "model" / "database.safetensors"))
    assert {"latent_frames", "motion_frames", "first"} <= set(stored) and "latents" not in stored
    bundle = load_bundle(root / "model")
    windows = {"codes": stored["codes"], "sequence": stored["sequence"], "start": stored["start"],
               "latents": bundle.database.latents.windows(), "motion": bundle.database.motion.windows()}
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    add_bundle_part(copy, "database.safetensors", windows, {}, numpy=True)
    old = load_bundle(copy)
    assert isinstance(old.database.latents, np.ndarray) and np.array_equal(old.database.latents, windows["latents"])
    motion = np.random.default_rng(0).normal(size=(3, *windows["motion"].shape[1:])).astype(np.float32)
    assert np.array_equal(old.database.nearest_motion(motion), bundle.database.nearest_motion(motion))
    spec = importlib.util.spec_from_file_location("compact_database", Path(__file__).parents[1] / "tools" / "compact_database.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    before, after = tool.compact(copy)  # tools/compact_database.py: back to the frame form, checked
    assert after < before and load_file(str(copy / "database.safetensors")).keys() == stored.keys()
    again = load_bundle(copy).database
    assert np.array_equal(again.latents.windows(), windows["latents"]) and np.array_equal(again.motion.frames, stored["motion_frames"])
