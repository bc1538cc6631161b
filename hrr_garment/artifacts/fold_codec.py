"""Four bits a value for the fold store: blocks of values sharing a scale, on a normal codebook.

The folds of a simulated frame (:mod:`.folds`) are high spatial frequencies, near noise to any
basis: on real-quick's dress 512 principal components keep 95 % of their variance, and patches of
about 48 vertices with 32 local components each still miss 13 % of their amplitude. Quantising
each value does better. The values of a block (:data:`BLOCK` values, 32 vertices x 3 in the
mesh's vertex order, which keeps neighbours together) share their largest magnitude as scale,
and each value is coded as the nearest of :data:`CODEBOOK`'s 15 levels, quantiles of a normal
distribution (as NF4 does for network weights, Dettmers et al. 2023): the folds' values cluster
near zero. On real-quick's folds (8.4 mm RMS) the rounding error is 0.86 mm RMS, against 0.97 for
even levels and 1.74 for one scale a frame; two codes a byte and a float16 scale a block make a
frame 0.52 of its int8 size (docs/decisions/0027-four-bit-folds.md).
"""

from __future__ import annotations

from statistics import NormalDist

import numpy as np

BLOCK = 96  # values sharing a scale: 32 vertices x 3 coordinates


def _normal_levels() -> np.ndarray:
    """15 levels in [-1, 1], symmetric, with 0: the normal distribution's quantiles at the middles
    of 7 equal slices of each half, scaled so that the outermost is 1."""
    # the standard library's inverse normal: scipy.stats would add 0.4 s to every bundle load
    half = np.array(
        [NormalDist().inv_cdf(p) for p in np.linspace(0.5 / 8, 0.5, 8)[:-1]]
    )  # 7 negative quantiles
    levels = np.sort(np.concatenate([half, [0.0], -half]))
    return (levels / np.abs(levels).max()).astype(np.float32)


CODEBOOK = _normal_levels()  # (15,) float32: code k stands for CODEBOOK[k] x its block's scale
_MIDPOINTS = (CODEBOOK[1:] + CODEBOOK[:-1]) / 2.0


def _pair_table() -> np.ndarray:
    """(65536,) complex128, each the four float32 levels of one little-endian byte pair's codes
    (code 15, which :func:`encode` never writes, read as the top level): decoding gathers 16 bytes
    per two code bytes, 8 x faster than unpacking the codes and gathering their levels one by one
    (0.16 against 1.3 ms for a crowd's 128 frames of the real-quick dress)."""
    pair = np.arange(65536)
    levels = CODEBOOK[np.minimum(np.arange(16), len(CODEBOOK) - 1)]
    table = np.stack([levels[(pair >> shift) & 15] for shift in (0, 4, 8, 12)], axis=1).astype(np.float32)
    return np.ascontiguousarray(table).view(np.complex128).ravel()


_PAIRS = _pair_table()


def blocks_of(num_values: int) -> int:
    """Blocks (each of :data:`BLOCK` values, the last padded) that hold ``num_values`` values."""
    return -(-int(num_values) // BLOCK)


def encode(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, n) float values -> ((T, blocks, BLOCK // 2) uint8 codes two a byte, the even value's in
    the low four bits; (T, blocks) float16 scales, each its block's largest magnitude)."""
    values = np.asarray(values, np.float32)
    t, n = values.shape
    padded = np.zeros((t, blocks_of(n) * BLOCK), np.float32)
    padded[:, :n] = values
    padded = padded.reshape(t, -1, BLOCK)
    scale = np.abs(padded).max(axis=2).astype(np.float16)
    # divide by the scale as stored, so that decoding with it gives the nearest level
    unit = padded / np.where(scale > 0, scale.astype(np.float32), 1.0)[..., None]
    codes = np.searchsorted(_MIDPOINTS, unit).astype(np.uint8)
    return (codes[..., 0::2] | (codes[..., 1::2] << 4)).astype(np.uint8), scale


def decode(codes: np.ndarray, scale: np.ndarray, num_values: int) -> np.ndarray:
    """The inverse of :func:`encode` (to its rounding): (T, blocks, BLOCK // 2) codes and (T, blocks)
    scales -> (T, num_values), float32 or the scales' wider type (scales times weights, say)."""
    pairs = np.ascontiguousarray(codes, np.uint8).view("<u2")  # the low byte first on any machine
    levels = np.take(_PAIRS, pairs).view(np.float32)  # (T, blocks, BLOCK)
    values = levels * np.asarray(scale, np.result_type(scale, np.float32))[..., None]
    return values.reshape(len(codes), -1)[:, :num_values]
