"""Retrieval database: every training window's garment code, its true garment latents and source.

Codes are G groups of K classes, stored as class indices (N, G). The similarity of two codes is
the cosine similarity of their one-hot vectors (length G x K, norm sqrt(G)), which is the fraction
of groups whose classes agree. On one-hot vectors that is exactly ``1 - hamming / (2 G)``, with the
Hamming distance of the packed bit vectors (each disagreeing group flips two bits), so the search
runs on a FAISS binary index (popcounts over G x K / 8 bytes per code) and returns the same
neighbours as a float inner-product index over the normalised one-hot vectors, 32x smaller.

Stride-1 windows share all but one frame with their neighbours, so a database built from a
dataset's sequences keeps each frame once (:class:`WindowFrames`) and reads a window as W
consecutive frames: ten times smaller than the windows themselves, on disk and in memory.

The gate signals that judge a match (:mod:`.gate_signals`) use :meth:`CodeDatabase.search` and
:meth:`CodeDatabase.motion_distance`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.windows import WindowFrames

RERANK = 8  # naive nearest neighbour: candidates ranked again in float64
FRAMES_KEY = {"latents": "latent_frames", "motion": "motion_frames"}  # a bundle's names for the frame form


def _faiss():
    """The FAISS module, imported where an index is built: everything up to the first database
    (training a mesh autoencoder on a bare GPU image, say) runs without it."""
    try:
        import faiss
    except ImportError:
        raise ImportError(
            "the retrieval database needs FAISS, a core dependency: pip install faiss-cpu"
        ) from None
    return faiss


def pack_codes(codes: np.ndarray, classes: int) -> np.ndarray:
    """(N, G) class indices -> (N, ceil(G * K / 8)) packed one-hot bits."""
    codes = np.asarray(codes)
    onehot = np.zeros((len(codes), codes.shape[1] * classes), bool)
    rows = np.repeat(np.arange(len(codes)), codes.shape[1])
    onehot[rows, (np.arange(codes.shape[1]) * classes + codes).reshape(-1)] = True
    return np.packbits(onehot, axis=1)


def code_similarity(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cosine similarity of one-hot codes: (Q, G) and (N, G) class indices -> (Q, N)."""
    return (np.asarray(a)[:, None, :] == np.asarray(b)[None, :, :]).mean(-1)


@dataclass
class CodeDatabase:
    """Every training window's garment code, true latents and source, searchable by code."""

    codes: np.ndarray  # (N, G) uint8 class indices of the garment codes
    latents: np.ndarray | WindowFrames  # (N, W, nodes, C) float32 true garment latents (not standardised)
    sequence: np.ndarray  # (N,) int32 index into names
    start: np.ndarray  # (N,) int32 first frame of the window
    names: list[str]
    classes: int
    motion: np.ndarray | WindowFrames | None = (
        None  # (N, W, F) standardised motion windows (naive NN, gate signals)
    )

    def __post_init__(self):
        self.codes = np.ascontiguousarray(self.codes, np.uint8)
        n, groups = self.codes.shape
        if not (len(self.latents) == len(self.sequence) == len(self.start) == n) or (
            self.motion is not None and len(self.motion) != n
        ):
            raise ValueError(
                f"database arrays disagree in length: codes {n}, latents {len(self.latents)}, "
                f"sequence {len(self.sequence)}, start {len(self.start)}"
            )
        if n and int(self.codes.max()) >= self.classes:
            raise ValueError(
                f"database codes use class {int(self.codes.max())} but there are {self.classes} classes"
            )
        self.groups = groups
        packed = pack_codes(self.codes, self.classes)
        self.index = _faiss().IndexBinaryFlat(packed.shape[1] * 8)
        self.index.add(packed)

    def __len__(self) -> int:
        return len(self.codes)

    def search(
        self, codes: np.ndarray, exclude: np.ndarray | None = None, conditions: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Best match per query code (Q, G): (indices (Q,), cosine similarity (Q,)).
        ``exclude`` (Q,): a sequence index per query whose windows may not be returned (-1: none).
        ``conditions`` (Q, c): each query's standardised body measures and cloth values (and the
        stillness clock's, where the model reads it), for a model trained across bodies or cloths
        (the last c columns of its motion frames): among the windows whose codes are equally near,
        the one simulated on the nearest body in the nearest cloth (at the nearest time after a stop)
        wins (its motion relative to the body carries over best, and its folds are its cloth's), ties
        to the lowest row."""
        if conditions is None or self.motion is None:
            dist, idx, _ = self._search(self.index, pack_codes(codes, self.classes), exclude)
            return idx[:, 0], 1.0 - dist[:, 0] / (2.0 * self.groups)
        dist, idx, allowed = self._search(self.index, pack_codes(codes, self.classes), exclude, RERANK)
        conditions = np.asarray(conditions, np.float64)
        theirs = self.motion[idx.reshape(-1), -1:][:, 0, -conditions.shape[1] :].reshape(*idx.shape, -1)
        apart = ((theirs - conditions[:, None]) ** 2).sum(-1)
        apart[~allowed | (dist != dist[:, :1])] = np.inf  # only the nearest codes compete
        rows = np.arange(len(idx))
        best = np.lexsort((idx, apart), axis=-1)[:, 0]
        return idx[rows, best], 1.0 - dist[rows, best] / (2.0 * self.groups)

    def _search(
        self, index, queries: np.ndarray, exclude: np.ndarray | None, n: int = 1
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ``n`` nearest rows per query in ``index`` (distances, rows, allowed; each (Q, n), in
        order of distance), skipping rows of the query's ``exclude`` sequence: enough neighbours are
        fetched that ``n`` lie outside the largest. Where fewer are allowed, the rest are marked
        not allowed; the first always is."""
        excluding = exclude is not None and np.any(np.asarray(exclude) >= 0)
        k = min(len(self), n + (int(np.bincount(self.sequence).max()) if excluding else 0))
        dist, idx = index.search(queries, k)
        allowed = (
            self.sequence[idx] != np.asarray(exclude)[:, None] if excluding else np.ones(idx.shape, bool)
        )
        if not allowed.any(1).all():
            raise ValueError("excluding the query's sequence leaves nothing to retrieve")
        rows, first = (
            np.arange(len(idx))[:, None],
            np.argsort(~allowed, axis=1, kind="stable")[:, :n],
        )  # allowed first, in order
        return dist[rows, first], idx[rows, first].astype(np.int64), allowed[rows, first]

    def nearest_motion(self, motion: np.ndarray, exclude: np.ndarray | None = None) -> np.ndarray:
        """Naive nearest neighbour (Euclidean on standardised motion windows (Q, W, F), no codes):
        the database row per query; the baseline that learned retrieval is compared with.

        FAISS finds candidates in float32 by a path that depends on how many queries come at once
        (BLAS for a batch, a loop for a few), so a near tie could go one way offline and the other
        in a stream. The best ``RERANK`` candidates are therefore ranked again in float64, ties to
        the lowest row: the same answer for a query alone or in a batch."""
        if self.motion is None:
            raise ValueError("this database has no motion windows (naive-NN needs them)")
        if not hasattr(
            self, "_motion_index"
        ):  # every window in full: the baseline's memory, built on first use
            windows = self.motion.windows() if isinstance(self.motion, WindowFrames) else self.motion
            self._motion_index = _faiss().IndexFlatL2(int(np.prod(windows.shape[1:])))
            self._motion_index.add(np.ascontiguousarray(windows.reshape(len(windows), -1), np.float32))
        q = np.ascontiguousarray(np.asarray(motion, np.float32).reshape(len(motion), -1))
        _, idx, allowed = self._search(self._motion_index, q, exclude, RERANK)
        cand = self.motion[idx.reshape(-1)].reshape(*idx.shape, -1).astype(np.float64)
        dist = np.where(allowed, ((cand - q[:, None].astype(np.float64)) ** 2).sum(-1), np.inf)
        best = np.lexsort((idx, dist), axis=-1)[:, 0]  # the nearest, ties to the lowest row
        return idx[np.arange(len(idx)), best]

    def motion_distance(self, motion: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """RMS difference (standardised units) between query motion windows (Q, W, F), standardised,
        and the database windows ``rows`` (Q,): how close a retrieved window's motion is to the query's."""
        if self.motion is None:
            raise ValueError("this database has no motion windows (the distance gate needs them)")
        diff = np.asarray(motion, np.float32).reshape(len(rows), -1) - self.motion[rows].reshape(
            len(rows), -1
        )
        return np.sqrt(np.mean(diff.astype(np.float64) ** 2, axis=1))

    def arrays(self) -> dict[str, np.ndarray]:
        """What a bundle stores: windows as frames (``latent_frames``, ``motion_frames`` and each
        window's ``first`` frame) when the database keeps them so, else as windows."""
        out = {"codes": self.codes, "sequence": self.sequence, "start": self.start}
        for name, value in (("latents", self.latents), ("motion", self.motion)):
            if isinstance(value, WindowFrames):
                out[FRAMES_KEY[name]], out["first"] = value.frames, value.first
            elif value is not None:
                out[name] = value
        return out

    @classmethod
    def from_arrays(
        cls, arrays: dict[str, np.ndarray], names: list[str], classes: int, window: int
    ) -> "CodeDatabase":
        """The database :meth:`arrays` stored (either form); ValueError when they do not fit."""

        def read(name: str):
            frames = FRAMES_KEY[name]
            if frames in arrays:
                if "first" not in arrays:
                    raise ValueError(f"{frames} without the windows' first frames")
                return WindowFrames(arrays[frames], arrays["first"], window)
            return arrays.get(name)

        latents = read("latents")
        if latents is None:
            raise ValueError("no garment latents (latent_frames or latents)")
        return cls(
            arrays["codes"], latents, arrays["sequence"], arrays["start"], names, classes, read("motion")
        )
