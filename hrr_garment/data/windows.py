"""Training windows for the code space: W consecutive frames of motion features and garment latents.

Every window of every sequence, stride 1: window i of a sequence covers frames i .. i + W - 1.
Statistics for standardising both sides are fitted on the training split's frames only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..motion.features import FeatureStats, motion_features
from ..motion.memory import MemorySpec, with_memory
from ..motion.windows import sequence_windows, windows


@dataclass
class WindowSet:
    """Windows of several sequences: ``motion`` (N, W, F), ``latents`` (N, W, nodes, C), and where
    each came from: ``sequence`` (N,) indices into ``names`` and ``start`` (N,) first frames."""

    motion: np.ndarray
    latents: np.ndarray
    sequence: np.ndarray
    start: np.ndarray
    names: list[str]

    def __len__(self) -> int:
        return len(self.motion)

    def subset(self, rows: np.ndarray) -> "WindowSet":
        """The windows ``rows`` (indices or a mask), ``names`` kept whole."""
        return WindowSet(self.motion[rows], self.latents[rows], self.sequence[rows], self.start[rows], self.names)


def split_windows(windows: WindowSet, fraction: float, seed: int = 0) -> tuple[WindowSet, WindowSet]:
    """The windows split at random, ``fraction`` of them into the second set: the paper's
    validation protocol (its clips' windows split 9:1). Neighbouring stride-1 windows share all but
    one frame, so a validation window's frames are nearly all in training too: this measures
    interpolation within the training clips, not generalisation."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"fraction must be strictly between 0 and 1, got {fraction}")
    order = np.random.default_rng(seed).permutation(len(windows))
    cut = int(round(len(windows) * fraction))
    if cut == 0 or cut == len(windows):
        raise ValueError(f"{len(windows)} windows cannot be split {1 - fraction:g} : {fraction:g}")
    return windows.subset(np.sort(order[cut:])), windows.subset(np.sort(order[:cut]))


def build_windows(features: dict[str, np.ndarray], latents: dict[str, np.ndarray], names: list[str], window: int) -> WindowSet:
    """Windows of the sequences ``names``; ``features[name]`` (T, F), ``latents[name]`` (T, nodes, C).
    Sequences shorter than one window contribute none."""
    motion, lat, seq, start = [], [], [], []
    for i, name in enumerate(names):
        f, z = features[name], latents[name]
        if len(f) != len(z):
            raise ValueError(f"sequence {name!r}: {len(f)} motion frames but {len(z)} latent frames")
        if len(f) < window:
            continue
        motion.append(windows(f, window, source=name))
        lat.append(sequence_windows(z, window))
        n = len(f) - window + 1
        seq.append(np.full(n, i, np.int32))
        start.append(np.arange(n, dtype=np.int32))
    if not motion:
        raise ValueError(f"no sequence has {window} frames or more")
    return WindowSet(np.ascontiguousarray(np.concatenate(motion), np.float32), np.ascontiguousarray(np.concatenate(lat), np.float32),
                     np.concatenate(seq), np.concatenate(start), list(names))


def dataset_features(dataset, names: list[str], memory: MemorySpec | Sequence[float]) -> dict[str, np.ndarray]:
    """Motion features (T, 124 + memory) of each named sequence of a :class:`GarmentDataset`, with
    the motion memory ``memory`` (:mod:`hrr_garment.motion.memory`)."""
    out = {}
    for name in names:
        motion = dataset.sequence(name).motion
        out[name] = with_memory(motion_features(motion), motion.fps, memory)
    return out


def fit_stats(features: dict[str, np.ndarray], latents: dict[str, np.ndarray], names: list[str]) -> tuple[FeatureStats, FeatureStats]:
    """Per-feature motion statistics and per-(node, channel) latent statistics over ``names``' frames."""
    motion = FeatureStats.fit([features[n] for n in names])
    lat = FeatureStats.fit([latents[n].reshape(len(latents[n]), -1) for n in names])
    return motion, lat
