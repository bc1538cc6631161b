"""Training windows (hrr_garment.data.windows): every start frame, the 9:1 window split."""

import numpy as np
import pytest

from hrr_garment.data.windows import build_windows


def test_windows_cover_every_start_frame():
    feats = {"a": np.arange(12 * 2, dtype=np.float32).reshape(12, 2), "b": np.zeros((9, 2), np.float32)}
    lat = {
        "a": np.arange(12 * 3 * 2, dtype=np.float32).reshape(12, 3, 2),
        "b": np.zeros((9, 3, 2), np.float32),
    }
    w = build_windows(feats, lat, ["a", "b"], 10)
    assert len(w) == 3  # b is shorter than a window
    assert w.motion.shape == (3, 10, 2) and w.latents.shape == (3, 10, 3, 2)
    assert len(w.motion.frames) == 12  # each frame once
    for i in range(3):
        assert np.array_equal(w.motion[i], feats["a"][i : i + 10]) and np.array_equal(
            w.latents[i], lat["a"][i : i + 10]
        )
    assert w.start.tolist() == [0, 1, 2] and w.sequence.tolist() == [0, 0, 0]


@pytest.mark.parametrize("seed", [0, 1])
def test_split_windows_partitions_the_windows_nine_to_one(seed):
    from hrr_garment.data.windows import split_windows

    feats = {n: np.random.default_rng(i).normal(size=(40, 2)).astype(np.float32) for i, n in enumerate("abc")}
    lat = {n: np.zeros((40, 3, 2), np.float32) for n in "abc"}
    every = build_windows(feats, lat, ["a", "b", "c"], 10)
    train, val = split_windows(every, 0.1, seed)
    assert len(val) == round(0.1 * len(every)) and len(train) + len(val) == len(every)
    pairs = lambda w: {(int(q), int(s)) for q, s in zip(w.sequence, w.start)}  # noqa: E731
    assert pairs(train) | pairs(val) == pairs(every) and not pairs(train) & pairs(val)
    for i in range(len(val)):  # each window keeps its own frames and source
        assert np.array_equal(val.motion[i], feats["abc"[val.sequence[i]]][val.start[i] : val.start[i] + 10])
    again = split_windows(every, 0.1, seed)[1]
    assert pairs(again) == pairs(val) and pairs(split_windows(every, 0.1, seed + 7)[1]) != pairs(val)
    with pytest.raises(ValueError):
        split_windows(every, 1.0)
