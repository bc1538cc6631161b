"""Which sequences to simulate when a budget cannot take a whole library: an order in which every
prefix covers the library's motion as well as it can, or a seeded random order to compare with.

    descriptors = window_descriptors([spec.motion() for spec in specs])
    order = coverage_order(descriptors)              # farthest-point sampling over the windows
    spread = coverage_distance(descriptors, order[:20])   # mean distance of every window to the nearest kept

Each sequence is described by its windows: one second of motion features (:func:`~hrr_garment.motion.
features.motion_features`) every half second, averaged, standardised over the library and reduced to
its leading principal directions (so that the position of a wrist and the speed of the root weigh
alike, and the features' many near-copies do not outvote the rest). The coverage order is
farthest-point sampling with whole sequences as the unit: it starts from the sequence holding the
window nearest the library's mean, then takes, again and again, the sequence holding the window
farthest from every window taken so far, so the farthest any window lies from a kept one shrinks as
fast as this greedy rule can make it. A random prefix of the same length leaves whole kinds of motion
out where the library has few of them (hanging from bars beside a hundred walks).
"""

from __future__ import annotations

import numpy as np

WINDOW_FRAMES = 30  # a window: one second at 30 frames a second
WINDOW_STRIDE = 15  # a window every half second
DIRECTIONS = 24  # principal directions kept of the standardised window means


def sequence_windows(features: np.ndarray) -> np.ndarray:
    """The window means of one sequence's motion features ``(T, F)``: ``(W, F)``; a sequence shorter
    than a window is one window."""
    count = len(features)
    if count <= WINDOW_FRAMES:
        return features.mean(axis=0, keepdims=True)
    starts = range(0, count - WINDOW_FRAMES + 1, WINDOW_STRIDE)
    return np.stack([features[s : s + WINDOW_FRAMES].mean(axis=0) for s in starts])


def window_descriptors(features: list[np.ndarray], directions: int = DIRECTIONS) -> list[np.ndarray]:
    """Every sequence's windows (:func:`sequence_windows` of its ``(T, F)`` features) standardised over
    the whole library and projected on its ``directions`` leading principal directions."""
    windows = [sequence_windows(np.asarray(f, dtype=np.float64)) for f in features]
    stacked = np.concatenate(windows)
    mean, scale = stacked.mean(axis=0), stacked.std(axis=0)
    scale[scale < 1e-9] = 1.0  # a feature constant over the library carries nothing
    centred = (stacked - mean) / scale
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    projected = centred @ vt[: min(directions, len(vt))].T
    bounds = np.cumsum([0] + [len(w) for w in windows])
    return [projected[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def coverage_order(descriptors: list[np.ndarray], first: list[int] | None = None) -> list[int]:
    """The sequences in farthest-point order (see the module docstring): each next one holds the
    window farthest from every window of those before it; ties go to the lower index. ``first``:
    sequences taken before any other, in their order (a character's own clips, the probe's), from
    which the sampling goes on; none: the one holding the window nearest the library's mean."""
    stacked = np.concatenate(descriptors)
    owner = np.repeat(np.arange(len(descriptors)), [len(d) for d in descriptors])
    order = list(
        dict.fromkeys(first or [int(owner[np.argmin(np.linalg.norm(stacked - stacked.mean(0), axis=1))])])
    )
    nearest = np.full(len(stacked), np.inf)
    taken = np.zeros(len(descriptors), dtype=bool)
    for pick in order:
        taken[pick] = True
        nearest = np.minimum(nearest, _nearest(stacked, descriptors[pick]))
    while not taken.all():
        # a window of a taken sequence lies at distance 0, so the farthest is always a new sequence's
        # (unless every window left duplicates a taken one: then the lowest index left)
        pick = int(owner[int(np.argmax(np.where(taken[owner], -1.0, nearest)))])
        order.append(pick)
        taken[pick] = True
        nearest = np.minimum(nearest, _nearest(stacked, descriptors[pick]))
    return order


def _nearest(windows: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Each of ``windows``' distance to the nearest of ``kept``."""
    return np.linalg.norm(windows[:, None] - kept[None], axis=2).min(axis=1)


def random_order(count: int, seed: int = 0) -> list[int]:
    """A seeded random order of ``count`` sequences (coverage selection's baseline)."""
    return [int(i) for i in np.random.default_rng(seed).permutation(count)]


def coverage_distance(descriptors: list[np.ndarray], chosen: list[int], statistic: str = "mean") -> float:
    """The mean (``statistic`` "max": the largest) distance from every window of the library to the
    nearest window of the ``chosen`` sequences: lower covers better, 0 when every sequence is chosen."""
    stacked = np.concatenate(descriptors)
    kept = np.concatenate([descriptors[i] for i in chosen])
    nearest = np.full(len(stacked), np.inf)
    for start in range(0, len(kept), 256):  # a block of kept windows at a time: bounded memory
        nearest = np.minimum(nearest, _nearest(stacked, kept[start : start + 256]))
    return float(nearest.max() if statistic == "max" else nearest.mean())
