"""Retrieval database: every training window's garment code, its true garment latents and source.

Codes are G groups of K classes, stored as class indices (N, G). The similarity of two codes is
the cosine similarity of their one-hot vectors (length G x K, norm sqrt(G)), which is the fraction
of groups whose classes agree. On one-hot vectors that is exactly ``1 - hamming / (2 G)``, with the
Hamming distance of the packed bit vectors (each disagreeing group flips two bits), so the search
runs on a FAISS binary index (popcounts over G x K / 8 bytes per code) and returns the same
neighbours as a float inner-product index over the normalised one-hot vectors, 32x smaller.
"""

from __future__ import annotations

from dataclasses import dataclass

import faiss
import numpy as np


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
    codes: np.ndarray  # (N, G) uint8 class indices of the garment codes
    latents: np.ndarray  # (N, W, nodes, C) float32 true garment latents (not standardised)
    sequence: np.ndarray  # (N,) int32 index into names
    start: np.ndarray  # (N,) int32 first frame of the window
    names: list[str]
    classes: int

    def __post_init__(self):
        self.codes = np.ascontiguousarray(self.codes, np.uint8)
        n, groups = self.codes.shape
        if not (len(self.latents) == len(self.sequence) == len(self.start) == n):
            raise ValueError(f"database arrays disagree in length: codes {n}, latents {len(self.latents)}, "
                             f"sequence {len(self.sequence)}, start {len(self.start)}")
        if n and int(self.codes.max()) >= self.classes:
            raise ValueError(f"database codes use class {int(self.codes.max())} but there are {self.classes} classes")
        self.groups = groups
        packed = pack_codes(self.codes, self.classes)
        self.index = faiss.IndexBinaryFlat(packed.shape[1] * 8)
        self.index.add(packed)

    def __len__(self) -> int:
        return len(self.codes)

    def search(self, codes: np.ndarray, exclude: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Best match per query code (Q, G): (indices (Q,), cosine similarity (Q,)).
        ``exclude`` (Q,): a sequence index per query whose windows may not be returned (-1: none)."""
        packed = pack_codes(codes, self.classes)
        if exclude is None or not np.any(np.asarray(exclude) >= 0):
            dist, idx = self.index.search(packed, 1)
            return idx[:, 0].astype(np.int64), 1.0 - dist[:, 0] / (2.0 * self.groups)
        exclude = np.asarray(exclude)
        # enough neighbours that at least one lies outside the largest excluded sequence
        k = min(len(self), int(np.bincount(self.sequence).max()) + 1)
        dist, idx = self.index.search(packed, k)
        allowed = self.sequence[idx] != exclude[:, None]
        first = allowed.argmax(1)
        rows = np.arange(len(idx))
        return idx[rows, first].astype(np.int64), 1.0 - dist[rows, first] / (2.0 * self.groups)

    def arrays(self) -> dict[str, np.ndarray]:
        return {"codes": self.codes, "latents": self.latents, "sequence": self.sequence, "start": self.start}
