"""The torch step's motion memory (inference.torch_features.FeatureStage) against the package's
(motion.memory.MotionMemory), frame by frame through a motion that moves, stops and stands, and
across a character's start: the graph an engine runs carries the same memory as a stream."""

import numpy as np
import pytest
import torch

from hrr_garment import motion_features, synthesize
from hrr_garment.inference.torch_features import FeatureStage
from hrr_garment.motion.compose import held_still
from hrr_garment.motion.memory import MemorySettings, MotionMemory


@pytest.mark.parametrize(
    "spec",
    [
        MemorySettings((0.5, 1.5), (0.6, 1.0)),
        MemorySettings((0.5,), (1.0,), 0.3, (1.0, 4.0)),
        MemorySettings((), (), 0.3, (2.0,)),
    ],
)
def test_the_graphs_memory_equals_the_packages_through_a_stop(spec):
    fps = 30.0
    clips = [
        motion_features(held_still(synthesize(kind, seconds=1.5, seed=2), 45)) for kind in ("walk", "spin")
    ]
    memory = MotionMemory(spec, fps)
    stage = FeatureStage(memory, fps, None, None)
    state = memory.start(np.stack([c[0] for c in clips]))
    graph_state = torch.zeros(2, spec.rows, 64)
    started = torch.tensor([0.0, 0.0])
    for t in range(len(clips[0])):
        frame = np.stack([c[t] for c in clips])
        if t:
            state = memory.step(state, frame)
        graph_state = stage.memory(graph_state, torch.as_tensor(frame), started)
        started = torch.ones(2)
        want, got = memory.values(state), stage.memory_values(graph_state).numpy()
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-4 * max(1.0, np.abs(want).max()))
