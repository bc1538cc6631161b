"""The torch step's motion memory (inference.torch_features.FeatureStage) against the package's
(motion.memory.MotionMemory), frame by frame through a motion that moves, stops and stands, with one
character starting later than the other: the graph an engine runs carries the same memory as a
stream, and its stillness clock gives the known answers."""

import numpy as np
import pytest
import torch

from hrr_garment import motion_features, synthesize
from hrr_garment.inference.torch_features import FeatureStage
from hrr_garment.motion.compose import held_still
from hrr_garment.motion.memory import MemorySettings, MotionMemory
from tests.motion.test_memory import CLOCK_SPEEDS, expected_clock, features_at_speeds

LATE = 3  # frames the second character starts after the first


def stepped_both_ways(spec: MemorySettings, clip: np.ndarray, fps: float):
    """(T, 2, width) memory values of two characters playing ``clip``, the second LATE frames behind
    (its rows before its start are not compared), from the package and from the graph."""
    memory, stage = MotionMemory(spec, fps), FeatureStage(MotionMemory(spec, fps), fps, None, None)
    states, graph_state, want, got = [None, None], torch.zeros(2, spec.rows, 64), [], []
    for t in range(len(clip)):
        frame = np.stack([clip[t], clip[max(t - LATE, 0)]])
        started = [t > 0, t > LATE]
        states = list(memory.advance([s if on else None for s, on in zip(states, started)], frame))
        graph_state = stage.memory(
            graph_state, torch.as_tensor(frame), torch.tensor(started, dtype=torch.float32)
        )
        want.append(memory.values(np.stack(states)))
        got.append(stage.memory_values(graph_state).numpy())
    return np.stack(want), np.stack(got)


@pytest.mark.parametrize(
    "spec",
    [
        MemorySettings((0.5, 1.5), (0.6, 1.0)),
        MemorySettings((0.5,), (1.0,), still_seconds=(1.0, 4.0)),
        MemorySettings(still_seconds=(2.0,)),
        MemorySettings((0.5,), (1.0,), held_seconds=(0.5, 2.0)),
        MemorySettings(held_seconds=(1.0,)),
    ],
)
def test_the_graphs_memory_equals_the_packages_through_a_stop(spec):
    fps = 30.0
    clip = motion_features(held_still(synthesize("spin", seconds=1.5, seed=2), 45))
    want, got = stepped_both_ways(spec, clip, fps)
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-4 * max(1.0, np.abs(want).max()))


def test_the_graphs_stillness_clock_gives_the_known_answers():
    fps, seconds = 30.0, np.array([1.0, 4.0])
    want = np.exp(-expected_clock(fps)[:, None] / seconds)
    spec = MemorySettings(still_seconds=tuple(seconds))
    _, got = stepped_both_ways(spec, features_at_speeds(CLOCK_SPEEDS), fps)
    np.testing.assert_allclose(got[:, 0], want, rtol=1e-5, atol=1e-30)
    np.testing.assert_allclose(got[LATE:, 1], want[: len(want) - LATE], rtol=1e-5, atol=1e-30)
