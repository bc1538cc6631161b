"""The detail mode's folds: the high spatial frequencies of every simulated frame in the database.

Everything decoded through the mesh autoencoder keeps about three quarters of the true frames'
bending energy, and a blend of overlapping windows averages much of the rest away; the simulated
frames themselves carry all of it. The store keeps, for every frame of every database sequence, in
the body frame (:mod:`hrr_garment.motion.frame`), what is left of the frame after ``passes``
passes of the mesh's 1-ring mean (:func:`~hrr_garment.garment.smoothing.high_frequencies`): its folds
and wrinkles, a few millimetres, without the shape. Rows are in the database's sequence order
(``offsets``), each frame stored in one of two encodings (:data:`ENCODINGS`):

- ``"nf4"`` (new stores, :data:`FOLD_ENCODING`): four bits a value on a normal codebook, a scale per
  32 vertices (:mod:`.fold_codec`); 0.52 of int8's size, the rounding 0.86 mm RMS on folds of 8.4
  mm, and the default look's PVE, hem swing and jitter as with int8 (decision 0027).
- ``"int8"`` (stores written before): int8 with one scale per frame, a quarter of float32, the
  rounding at most half a step (about 0.1 mm on a dress).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix

from ..garment.smoothing import high_frequencies
from . import fold_codec
from .manifest_entries import FoldsEntry

#: folds.safetensors' key for each field, where it differs (the file format keeps its first name)
FILE_KEYS = {"levels": "detail"}
MAX_PASSES = 16  # what a bundle may ask: each pass is a smoothing of every frame at run time (1e6 would hang)
FOLD_PASSES = (
    1  # passes of the 1-ring mean that separate the folds from the shape (docs/history/results-log.md)
)
DETAIL_STRENGTH = 0.8  # the folds' strength where a bundle's auto mode was not calibrated (.manifest)
ENCODINGS = ("int8", "nf4")
FOLD_ENCODING = "nf4"  # what new stores are written in (the module docstring)


@dataclass
class FoldStore:
    """Every database frame's folds: ``folds(rows, weights)`` gives weighted sums of them."""

    # each frame's high frequencies: int8 (N, V, 3) in steps of its scale; nf4 (N, blocks, 48) uint8,
    # two 4-bit codes a byte (.fold_codec)
    levels: np.ndarray
    scale: np.ndarray  # int8: (N,) float32 metres per step; nf4: (N, blocks) float16 metres per block
    offsets: np.ndarray  # (S + 1,) int64: sequence s's frames are rows offsets[s] .. offsets[s + 1] - 1
    passes: int = FOLD_PASSES
    encoding: str = "int8"
    vertices: int | None = None  # V, which nf4's padded blocks do not tell (int8: its levels' shape)

    def __post_init__(self) -> None:
        self.levels = np.asarray(self.levels)
        self.offsets = np.asarray(self.offsets, np.int64)
        if self.encoding not in ENCODINGS:
            raise ValueError(f"fold encoding must be one of {', '.join(ENCODINGS)}, got {self.encoding!r}")
        if self.encoding == "int8":
            self._check_int8()
        else:
            self._check_nf4()
        if (
            self.scale.shape != self.levels.shape[: self.scale.ndim]
            or not np.isfinite(self.scale).all()
            or (self.scale < 0).any()
        ):
            raise ValueError(
                f"fold scales must be finite numbers >= 0, one per frame (int8) or per block (nf4), "
                f"got shape {self.scale.shape}"
            )
        o = self.offsets
        if o.ndim != 1 or len(o) < 1 or o[0] != 0 or o[-1] != len(self.levels) or (np.diff(o) < 0).any():
            raise ValueError(f"fold offsets must rise from 0 to {len(self.levels)}")
        if (
            isinstance(self.passes, bool)
            or not isinstance(self.passes, (int, np.integer))
            or not 1 <= self.passes <= MAX_PASSES
        ):
            raise ValueError(
                f"fold passes must be a whole number from 1 to {MAX_PASSES}, got {self.passes!r}"
            )
        self.passes = int(self.passes)

    def _check_int8(self) -> None:
        self.scale = np.asarray(self.scale, np.float32)
        if self.levels.dtype != np.int8 or self.levels.ndim != 3 or self.levels.shape[2] != 3:
            raise ValueError(
                f"fold levels must be (N, V, 3) int8, got {self.levels.shape} {self.levels.dtype}"
            )
        if self.vertices is not None and self.vertices != self.levels.shape[1]:
            raise ValueError(f"fold levels hold {self.levels.shape[1]} vertices, not {self.vertices}")
        if self.scale.ndim != 1:
            raise ValueError(f"int8 fold scales must be one per frame, got shape {self.scale.shape}")
        self.vertices = int(self.levels.shape[1])

    def _check_nf4(self) -> None:
        self.scale = np.asarray(self.scale, np.float16)
        v = self.vertices
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"nf4 folds need their number of vertices, got {v!r}")
        blocks = fold_codec.blocks_of(3 * v)
        if self.levels.dtype != np.uint8 or self.levels.shape[1:] != (blocks, fold_codec.BLOCK // 2):
            raise ValueError(
                f"nf4 fold codes of {v} vertices must be (N, {blocks}, {fold_codec.BLOCK // 2}) uint8, "
                f"got {self.levels.shape} {self.levels.dtype}"
            )
        if self.scale.ndim != 2:
            raise ValueError(f"nf4 fold scales must be one per block, got shape {self.scale.shape}")
        self.vertices = int(v)

    @classmethod
    def build(
        cls,
        sequences: Iterable[np.ndarray],
        mean: csr_matrix,
        passes: int = FOLD_PASSES,
        encoding: str = FOLD_ENCODING,
    ) -> "FoldStore":
        """From each database sequence's body-frame vertices (T_s, V, 3), in the database's order."""
        detail, scale, lengths, vertices = [], [], [0], None
        for frames in sequences:
            high = high_frequencies(frames, mean, passes)
            vertices = high.shape[1]
            if encoding == "nf4":
                codes, block_scale = fold_codec.encode(high.reshape(len(high), -1))
                detail.append(codes)
                scale.append(block_scale)
            else:
                step = np.abs(high).max(axis=(1, 2)) / 127.0
                detail.append(np.round(high / np.where(step > 0, step, 1.0)[:, None, None]).astype(np.int8))
                scale.append(step.astype(np.float32))
            lengths.append(len(frames))
        if len(detail) == 0:
            raise ValueError("a fold store needs at least one sequence")
        return cls(
            np.concatenate(detail), np.concatenate(scale), np.cumsum(lengths), passes, encoding, vertices
        )

    @property
    def lengths(self) -> np.ndarray:
        """(S,) frames of each sequence."""
        return np.diff(self.offsets)

    @property
    def num_vertices(self) -> int:
        return int(self.vertices)

    def frames(self, rows: np.ndarray, weights: np.ndarray | float = 1.0) -> np.ndarray:
        """(n,) store rows (and (n,) weights) -> (n, V, 3) those frames' folds in metres, each times
        its weight (float64 from an int8 store, float32 from an nf4 one)."""
        weights = np.broadcast_to(np.asarray(weights, np.float64), np.shape(rows))
        if self.encoding == "int8":
            return (weights * self.scale[rows])[:, None, None] * self.levels[rows]
        # float32 products: half the memory traffic of float64, and their rounding far below the codes'
        scale = (weights[:, None] * self.scale[rows]).astype(np.float32)
        values = fold_codec.decode(self.levels[rows], scale, 3 * self.num_vertices)
        return values.reshape(len(values), self.num_vertices, 3)

    def rows(self, sequence: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """Store rows of (database sequence, frame) pairs (any matching shapes)."""
        sequence, frame = np.asarray(sequence, np.int64), np.asarray(frame, np.int64)
        if ((frame < 0) | (frame >= self.lengths[sequence])).any():
            raise IndexError("a fold frame outside its sequence")
        return self.offsets[sequence] + frame

    def folds(self, rows: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """(T, K) rows and weights -> (T, V, 3) float64: each frame's weighted sum of those rows' folds
        (weights of 0 read nothing)."""
        rows, weights = np.asarray(rows), np.asarray(weights, np.float64)
        if self.encoding == "nf4":  # every row in one decode, the weights in the scales, summed over K
            used = weights != 0
            frames = self.frames(np.where(used, rows, 0).ravel(), np.where(used, weights, 0.0).ravel())
            return frames.reshape(*rows.shape, self.num_vertices, 3).sum(axis=1, dtype=np.float64)
        out = np.zeros((len(rows), self.num_vertices, 3))
        for k in range(rows.shape[1]):
            used = weights[:, k] != 0
            if used.any():
                r = rows[used, k]
                out[used] += self.frames(r, weights[used, k])
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        return {FILE_KEYS["levels"]: self.levels, "scale": self.scale, "offsets": self.offsets}

    @property
    def entry(self) -> FoldsEntry:
        """bundle.json's ``folds`` entry."""
        return FoldsEntry.parse(
            {
                "passes": self.passes,
                "frames": len(self.levels),
                "encoding": self.encoding,
                "vertices": self.num_vertices,
            },
            "folds",
        )

    def check_fits(self, num_vertices: int, sequences: int, sequence: np.ndarray, end: np.ndarray) -> None:
        """A ValueError unless the store fits a model: ``num_vertices`` per frame, ``sequences``
        database sequences, and frames up to ``end`` (exclusive) of each database window's ``sequence``."""
        if self.num_vertices != num_vertices or len(self.lengths) != sequences:
            raise ValueError(
                f"it holds {len(self.lengths)} sequences of {self.num_vertices} vertices; the model has "
                f"{sequences} of {num_vertices}"
            )
        if len(sequence) and (end > self.lengths[sequence]).any():
            raise ValueError("it is shorter than the database windows it must cover")
