"""The coverage order (hrr_garment.sim.coverage): farthest-point sampling over motion windows reaches
a rare kind of motion at once where a random order of the same length may not, and covers the
library better at every prefix on a library of known clusters."""

import numpy as np
import pytest

from hrr_garment.sim.coverage import (
    WINDOW_FRAMES,
    WINDOW_STRIDE,
    coverage_distance,
    coverage_order,
    random_order,
    sequence_windows,
    window_descriptors,
)


def _library(rng, common: int = 40, rare: int = 2):
    """Sequences of (T, 6) features: many near one pose, a few far away (hanging among walks)."""
    walks = [rng.normal(0.0, 0.1, (rng.integers(40, 120), 6)) for _ in range(common)]
    hangs = [rng.normal(5.0, 0.1, (90, 6)) for _ in range(rare)]
    return walks + hangs


def test_windows_are_one_second_every_half_second():
    features = np.arange(100 * 3, dtype=float).reshape(100, 3)
    windows = sequence_windows(features)
    assert windows.shape == (1 + (100 - WINDOW_FRAMES) // WINDOW_STRIDE, 3)
    np.testing.assert_allclose(windows[1], features[WINDOW_STRIDE : WINDOW_STRIDE + WINDOW_FRAMES].mean(0))
    assert sequence_windows(features[:10]).shape == (1, 3)  # shorter than a window: one


def test_descriptors_are_standardised_over_the_library(rng):
    library = _library(rng)
    described = window_descriptors(library, directions=4)
    assert [len(d) for d in described] == [len(sequence_windows(f)) for f in library]
    stacked = np.concatenate(described)
    assert stacked.shape[1] == 4
    np.testing.assert_allclose(stacked.mean(0), 0.0, atol=1e-9)  # centred before the projection


def test_the_rare_motion_comes_second(rng):
    library = _library(rng)
    order = coverage_order(window_descriptors(library))
    assert sorted(order) == list(range(len(library)))  # every sequence once
    assert order[0] < 40  # starts from the typical motion
    assert order[1] >= 40  # then the farthest: a rare clip


def test_each_next_sequence_holds_the_farthest_window(rng):
    """The order's rule, checked step by step: the next sequence holds the window farthest from every
    window taken before it, so the farthest distance never grows and is 0 once all are taken."""
    library = _library(rng, common=12, rare=3)
    described = window_descriptors(library)
    order = coverage_order(described)
    radii = []
    for k in range(1, len(order)):
        kept = np.concatenate([described[i] for i in order[:k]])
        farthest = [np.linalg.norm(d[:, None] - kept[None], axis=2).min(axis=1).max() for d in described]
        left = [i for i in range(len(library)) if i not in order[:k]]
        assert farthest[order[k]] == pytest.approx(max(farthest[i] for i in left))
        radii.append(coverage_distance(described, order[:k], "max"))
    assert all(a >= b - 1e-12 for a, b in zip(radii, radii[1:]))
    assert coverage_distance(described, order) == 0.0


def test_distinct_rare_motions_all_come_first(rng):
    """Three rare kinds of motion, each far from the rest and from each other: the first four
    sequences of the order hold all three (a random four of 33 rarely holds one)."""
    walks = [rng.normal(0.0, 0.1, (60, 6)) for _ in range(30)]
    rare = [np.eye(6)[k] * 6 + rng.normal(0.0, 0.1, (60, 6)) for k in range(3)]
    order = coverage_order(window_descriptors(walks + rare))
    assert set(order[:4]) >= {30, 31, 32}


def test_random_order_is_seeded():
    assert random_order(10, seed=3) == random_order(10, seed=3)
    assert sorted(random_order(10, seed=3)) == list(range(10))
    assert random_order(10, seed=3) != random_order(10, seed=4)


def test_sampling_goes_on_from_the_sequences_taken_first(rng):
    """Given sequences to take first (a character's own clips, the probe's), the order starts with
    them and the next is the farthest from them, not from the library's typical clip."""
    walks = [rng.normal(0.0, 0.1, (60, 6)) for _ in range(10)]
    far = [
        np.eye(6)[0] * 6 + rng.normal(0.0, 0.1, (60, 6)),
        -np.eye(6)[0] * 9 + rng.normal(0.0, 0.1, (60, 6)),
    ]
    described = window_descriptors(walks + far)
    order = coverage_order(described, first=[11, 3])
    assert order[:2] == [11, 3]
    assert order[2] == 10  # the other far clip: the farthest from both taken
    assert sorted(order) == list(range(12))
