"""Training windows for the code space: W consecutive frames of motion features and garment latents.

Every window of every sequence, stride 1: window i of a sequence covers frames i .. i + W - 1.
Neighbouring windows share all but one frame, so each frame is stored once and a window is read
as W consecutive rows (:class:`WindowFrames`): the real-motion library's 76,000 training windows
would take 3.6 GB as windows and take 0.4 GB as frames.
Statistics for standardising both sides are fitted on the training split's frames only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..body.measures import body_vector, with_columns
from ..garment.material_range import material_vector
from ..motion.features import FeatureStats, motion_features
from ..motion.memory import with_memory


class WindowFrames:
    """Windows of W consecutive rows of a per-frame array, read like an (N, W, ...) array of
    windows: row i is ``frames[first[i] : first[i] + W]``. Indexing gathers (``[rows]``,
    ``[rows, -k:]``); nothing else of numpy's array interface is offered."""

    def __init__(self, frames: np.ndarray, first: np.ndarray, window: int):
        self.frames, self.first, self.window = frames, np.asarray(first, np.int64), int(window)
        if self.window < 1 or self.first.ndim != 1:
            raise ValueError(
                f"a window needs at least one frame and one first frame per window, got window {window} "
                f"and first frames of shape {self.first.shape}"
            )
        if len(self.first) and (self.first.min() < 0 or self.first.max() + self.window > len(frames)):
            raise ValueError(
                f"windows of {self.window} frames from frames "
                f"{int(self.first.min())}-{int(self.first.max())} run past the {len(frames)} frames stored"
            )

    @classmethod
    def of_windows(
        cls, windows: np.ndarray, sequence: np.ndarray, start: np.ndarray, chunk: int = 4096
    ) -> "WindowFrames":
        """Stride-1 windows (N, W, ...) cut from sequences (each one's ``sequence`` and ``start``)
        back into their frames; ValueError where two windows disagree about a frame they share."""
        n, window = windows.shape[:2]
        sequence, start = np.asarray(sequence, np.int64), np.asarray(start, np.int64)
        ends = np.zeros(int(sequence.max()) + 1 if n else 0, np.int64)
        np.maximum.at(ends, sequence, start + window)
        offsets = np.concatenate([[0], np.cumsum(ends)])
        rows = (offsets[sequence] + start)[:, None] + np.arange(window)
        frames = np.zeros((int(offsets[-1]), *windows.shape[2:]), windows.dtype)
        frames[rows.reshape(-1)] = windows.reshape(n * window, *windows.shape[2:])
        covered = np.zeros(len(frames), bool)
        covered[rows.reshape(-1)] = True
        out = cls(
            frames[covered], (np.cumsum(covered) - 1)[rows[:, 0]], window
        )  # frames no window holds dropped
        for i in range(0, n, chunk):
            if not np.array_equal(out[np.arange(i, min(n, i + chunk))], windows[i : i + chunk]):
                raise ValueError(
                    "the windows are not stride-1 crops of sequences: two disagree about a frame they share"
                )
        return out

    @classmethod
    def of_sequences(
        cls, frames: list[np.ndarray], sequence: np.ndarray, start: np.ndarray, window: int
    ) -> "WindowFrames":
        """Windows (``sequence``, ``start`` each) of the per-frame arrays ``frames`` of sequences
        (T_s, ...), stored one after another."""
        offsets = np.concatenate([[0], np.cumsum([len(f) for f in frames])])
        return cls(np.concatenate(frames), offsets[np.asarray(sequence)] + np.asarray(start), window)

    def __len__(self) -> int:
        return len(self.first)

    def subset(self, rows) -> "WindowFrames":
        """The windows ``rows`` (indices or a mask) over the same frames (not copied)."""
        return WindowFrames(self.frames, self.first[rows], self.window)

    def with_frames(self, frames: np.ndarray) -> "WindowFrames":
        """The same windows over other values of the same frames (``frames`` one row per stored
        frame: standardised, say)."""
        if len(frames) != len(self.frames):
            raise ValueError(f"{len(frames)} frames given for windows over {len(self.frames)}")
        return WindowFrames(frames, self.first, self.window)

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self.first), self.window, *self.frames.shape[1:])

    @property
    def dtype(self) -> np.dtype:
        return self.frames.dtype

    def __getitem__(self, key) -> np.ndarray:
        rows, within = key if isinstance(key, tuple) else (key, slice(None))
        return self.frames[self.first[rows][..., None] + np.arange(self.window)[within]]

    def windows(self) -> np.ndarray:
        """Every window, (N, W, ...): W times the memory of the frames."""
        return self[np.arange(len(self))]


@dataclass
class WindowSet:
    """Windows of several sequences: ``motion`` (N, W, F) and ``latents`` (N, W, nodes, C), read
    from each frame stored once (:class:`WindowFrames`), and where each came from: ``sequence`` (N,)
    indices into ``names`` and ``start`` (N,) first frames."""

    motion: WindowFrames
    latents: WindowFrames
    sequence: np.ndarray
    start: np.ndarray
    names: list[str]

    def __len__(self) -> int:
        return len(self.sequence)

    def subset(self, rows: np.ndarray) -> "WindowSet":
        """The windows ``rows`` (indices or a mask), their frames shared and ``names`` kept whole."""
        return WindowSet(
            self.motion.subset(rows),
            self.latents.subset(rows),
            self.sequence[rows],
            self.start[rows],
            self.names,
        )


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


def build_windows(
    features: dict[str, np.ndarray], latents: dict[str, np.ndarray], names: list[str], window: int
) -> WindowSet:
    """Windows of the sequences ``names``; ``features[name]`` (T, F), ``latents[name]`` (T, nodes, C).
    Sequences shorter than one window contribute none."""
    kept, seq, start = [], [], []
    for i, name in enumerate(names):
        f, z = features[name], latents[name]
        if len(f) != len(z):
            raise ValueError(f"sequence {name!r}: {len(f)} motion frames but {len(z)} latent frames")
        if len(f) < window:
            continue
        kept.append(name)
        n = len(f) - window + 1
        seq.append(np.full(n, i, np.int32))
        start.append(np.arange(n, dtype=np.int32))
    if not kept:
        raise ValueError(f"no sequence has {window} frames or more")
    seq, start = np.concatenate(seq), np.concatenate(start)
    # the frames of the sequences with windows, one after another; ``rank`` numbers those sequences
    rank = np.cumsum([name in kept for name in names]) - 1
    motion = WindowFrames.of_sequences(
        [np.asarray(features[n], np.float32) for n in kept], rank[seq], start, window
    )
    lat = WindowFrames.of_sequences(
        [np.asarray(latents[n], np.float32) for n in kept], rank[seq], start, window
    )
    return WindowSet(motion, lat, seq, start, list(names))


def dataset_features(dataset, names: list[str], config) -> dict[str, np.ndarray]:
    """Motion features (T, F) of each named sequence of a :class:`GarmentDataset` as a code space
    of settings ``config`` (a :class:`~hrr_garment.models.codespace.CodeSpaceSettings`) reads them:
    the motion memory (:mod:`hrr_garment.motion.memory`) and, where it has their columns, the
    measures of the body each sequence was simulated on (:mod:`hrr_garment.body.measures`) and the
    values of the cloth it was simulated in (:mod:`hrr_garment.garment.material_range`)."""
    out = {}
    for name in names:
        motion = dataset.sequence(name).motion
        out[name] = with_memory(motion_features(motion), motion.fps, config.memory)
        if config.body_features:
            out[name] = with_columns(
                out[name], body_vector(dataset.bodies[dataset.body_name_of[name]].record)
            )
        if config.material_features:
            out[name] = with_columns(out[name], material_vector(dataset.material_of(name)))
    return out


def fit_stats(
    features: dict[str, np.ndarray], latents: dict[str, np.ndarray], names: list[str]
) -> tuple[FeatureStats, FeatureStats]:
    """Per-feature motion statistics and per-(node, channel) latent statistics over ``names``' frames."""
    motion = FeatureStats.fit([features[n] for n in names])
    lat = FeatureStats.fit([latents[n].reshape(len(latents[n]), -1) for n in names])
    return motion, lat
