"""Windows keep each frame once (hrr_garment.data.windows.WindowFrames), in training and in the
retrieval database: reading windows from frames gives the windows themselves, every search and
distance is unchanged, a bundle stores the frames, and bundles that stored every window still load."""

import importlib.util
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.numpy import load_file

from hrr_garment.artifacts.bundle_loader import load_bundle
from hrr_garment.artifacts.bundle_writer import add_bundle_part
from hrr_garment.artifacts.database import CodeDatabase
from hrr_garment.data.windows import WindowFrames, WindowSet, build_windows

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
    frames = w.latents
    assert (
        len(frames) == len(w) == 6 + 4
        and frames.shape == (10, WINDOW, 3, 2)
        and w.motion.shape == (10, WINDOW, 5)
    )
    assert (
        len(frames.frames) == len(w.motion.frames) == 9 + 7
    )  # each frame once; the short sequence has no window
    by_hand = np.stack([latents[names[q]][s : s + WINDOW] for q, s in zip(w.sequence, w.start)])
    rows = np.array([7, 0, 7, 3])
    assert np.array_equal(frames[rows], by_hand[rows])
    assert np.array_equal(frames[rows, -1:], by_hand[rows, -1:])
    assert np.array_equal(frames[5], by_hand[5]) and np.array_equal(
        frames[w.sequence == 2], by_hand[w.sequence == 2]
    )
    assert np.array_equal(frames.windows(), by_hand)
    assert np.array_equal(w.motion[8], motion["b"][2 : 2 + WINDOW])
    part = w.subset(np.array([9, 1]))  # a subset shares the frames
    assert part.latents.frames is frames.frames and np.array_equal(part.latents.windows(), by_hand[[9, 1]])
    doubled = frames.with_frames(2 * frames.frames)
    assert np.array_equal(doubled[rows], 2 * by_hand[rows])
    with pytest.raises(ValueError, match="3 frames given for windows over 16"):
        frames.with_frames(frames.frames[:3])
    with pytest.raises(ValueError, match="run past the 16 frames"):
        WindowFrames(frames.frames, np.array([0, 13]), WINDOW)


def test_training_reads_its_standardised_windows_from_frames():
    from hrr_garment.data.windows import fit_stats
    from hrr_garment.train.codespace_losses import WindowTensors

    motion, latents, names = sequences(3)
    w = build_windows(motion, latents, names, WINDOW)
    motion_stats, latent_stats = fit_stats(motion, latents, names)
    tensors = WindowTensors.of(w, motion_stats, latent_stats)
    assert len(tensors) == len(w) and len(tensors.motion) == len(w.motion.frames)  # frames, not windows
    rows = np.array([9, 0, 4])
    m, z = tensors[torch.from_numpy(rows)]
    np.testing.assert_allclose(m.numpy(), motion_stats.normalize(w.motion[rows]), rtol=1e-6)
    by_hand = latent_stats.normalize(w.latents[rows].reshape(3, WINDOW, -1)).reshape(3, WINDOW, 3, 2)
    np.testing.assert_allclose(z.numpy(), by_hand, rtol=1e-6)
    m, z = tensors[2:5]  # a slice, as validation reads them
    assert m.shape == (3, WINDOW, 5) and z.shape == (3, WINDOW, 3, 2)
    np.testing.assert_allclose(m.numpy(), motion_stats.normalize(w.motion[np.arange(2, 5)]), rtol=1e-6)
    skewed = WindowSet(w.motion.subset(np.arange(1, 11) % 10), w.latents, w.sequence, w.start, names)
    with pytest.raises(ValueError, match="not read from the same frames"):
        WindowTensors.of(skewed, motion_stats, latent_stats)


def test_a_database_of_frames_answers_as_the_one_of_windows_and_stores_them_once():
    motion, latents, names = sequences(1)
    w = build_windows(motion, latents, names, WINDOW)
    codes = np.random.default_rng(2).integers(0, 4, (len(w), 6))
    w_latents, w_motion = (
        w.latents.windows(),
        w.motion.windows(),
    )  # every window in full, as bundles stored them
    whole = CodeDatabase(codes, w_latents, w.sequence, w.start, names, 4, w_motion)
    framed = CodeDatabase(codes, w.latents, w.sequence, w.start, names, 4, w.motion)
    query = w.motion[[1, 8, 4]] + 0.01
    assert np.array_equal(framed.nearest_motion(query), whole.nearest_motion(query))
    assert np.array_equal(
        framed.nearest_motion(query, np.array([0, 2, -1])), whole.nearest_motion(query, np.array([0, 2, -1]))
    )
    batch = framed.nearest_motion(query)
    assert [int(framed.nearest_motion(q[None])[0]) for q in query] == batch.tolist()  # alone = in a batch
    twins = CodeDatabase(
        codes[:4], w_latents[:4], np.zeros(4, np.int32), np.arange(4), names, 4, w_motion[[2, 1, 2, 3]]
    )
    assert twins.nearest_motion(w.motion[[2]])[0] == 0  # an exact tie goes to the lowest row
    rows = np.array([2, 9, 0])
    np.testing.assert_allclose(
        framed.motion_distance(query, rows), whole.motion_distance(query, rows), rtol=1e-6
    )
    stored = framed.arrays()
    assert "latents" not in stored and "motion" not in stored
    assert stored["latent_frames"].size * WINDOW > w_latents.size  # fewer values than the windows ...
    assert stored["latent_frames"].size < w_latents.size  # ... by about the window's length
    again = CodeDatabase.from_arrays(stored, names, 4, WINDOW)
    assert np.array_equal(again.latents[np.arange(len(w))], w_latents) and np.array_equal(
        again.motion.windows(), w_motion
    )
    old = CodeDatabase.from_arrays(
        whole.arrays(), names, 4, WINDOW
    )  # the windows themselves, as bundles stored them
    assert np.array_equal(old.latents, w_latents)
    back = WindowFrames.of_windows(w_latents, w.sequence, w.start)  # the windows back into frames
    assert (
        np.array_equal(back.windows(), w_latents) and len(back.frames) == 9 + 7
    )  # the short sequence has no window
    bad = w_latents.copy()
    bad[1, 0] += 1.0  # window 1's first frame is window 0's second
    with pytest.raises(ValueError, match="not stride-1 crops"):
        WindowFrames.of_windows(bad, w.sequence, w.start)
    with pytest.raises(ValueError, match="without the windows' first frames"):
        CodeDatabase.from_arrays({k: v for k, v in stored.items() if k != "first"}, names, 4, WINDOW)


@pytest.mark.tool
def test_a_trained_bundle_stores_frames_and_one_that_stored_windows_still_loads(trained, tmp_path):
    root, _, _ = trained
    stored = load_file(str(root / "model" / "database.safetensors"))
    assert {"latent_frames", "motion_frames", "first"} <= set(stored) and "latents" not in stored
    bundle = load_bundle(root / "model")
    windows = {
        "codes": stored["codes"],
        "sequence": stored["sequence"],
        "start": stored["start"],
        "latents": bundle.database.latents.windows(),
        "motion": bundle.database.motion.windows(),
    }
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    add_bundle_part(copy, "database.safetensors", windows, numpy=True)
    old = load_bundle(copy)
    assert isinstance(old.database.latents, np.ndarray) and np.array_equal(
        old.database.latents, windows["latents"]
    )
    motion = np.random.default_rng(0).normal(size=(3, *windows["motion"].shape[1:])).astype(np.float32)
    assert np.array_equal(old.database.nearest_motion(motion), bundle.database.nearest_motion(motion))
    spec = importlib.util.spec_from_file_location(
        "compact_database", Path(__file__).parents[2] / "tools" / "compact_database.py"
    )
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    before, after = tool.compact(copy)  # tools/compact_database.py: back to the frame form, checked
    assert after < before and load_file(str(copy / "database.safetensors")).keys() == stored.keys()
    again = load_bundle(copy).database
    assert np.array_equal(again.latents.windows(), windows["latents"]) and np.array_equal(
        again.motion.frames, stored["motion_frames"]
    )


@pytest.mark.slow  # a fresh interpreter importing torch and the training commands: about 7 s
def test_everything_before_a_database_runs_without_faiss():
    """FAISS is imported where an index is built, so training a mesh autoencoder needs none (a bare
    GPU image); building a database without it says what to install."""
    import subprocess
    import sys

    script = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'faiss': raise ImportError('no faiss here')\n"
        "sys.meta_path.insert(0, Block())\n"
        "import numpy as np\n"
        "import hrr_garment.cli.train, hrr_garment.train.autoencoder, hrr_garment.inference.animator\n"
        "from hrr_garment.artifacts.database import CodeDatabase\n"
        "try:\n"
        "    CodeDatabase(np.zeros((2, 3), np.uint8), np.zeros((2, 4, 3, 2), np.float32), "
        "np.zeros(2, np.int32),\n"
        "                 np.zeros(2, np.int32), ['a'], 4)\n"
        "except ImportError as exc:\n"
        "    print(exc)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "pip install faiss-cpu" in done.stdout
