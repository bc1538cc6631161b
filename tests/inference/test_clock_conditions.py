"""A model whose garment encoder and decoder read the stillness clock beside the code, and whose
memory holds averages through a stop (``codespace: {model: {still_seconds: [...], held_seconds:
[...], clock_conditions: true}}``), trained on the shared tiny model's data: its decoder's inputs,
and through a stop its stream equals its causal clip, its torch crowd (the ONNX graph's step) its
native crowd and its ONNX graph its stream."""

import shutil

import numpy as np
import pytest

from hrr_garment.motion.compose import held_still
from hrr_garment.motion.poses import motion_to_poses
from hrr_garment.motion.synth import synthesize

CLOCK = (0.5, 2.0)
HELD = (1.0,)


@pytest.fixture(scope="module")
def clocked(trained, tmp_path_factory):
    from hrr_garment.inference.animator import Animator
    from tests.conftest import train_tiny

    root, data, args = trained
    folder = tmp_path_factory.mktemp("clocked") / "model"
    shutil.copytree(root / "model", folder)  # the autoencoder kept, the code space trained anew
    overrides = {
        "codespace": {
            "model": {"still_seconds": list(CLOCK), "held_seconds": list(HELD), "clock_conditions": True}
        }
    }
    train_tiny(data, folder, args[3], stages=("codespace",), overrides=overrides)
    return Animator.load(folder)


def _stopping():
    return held_still(synthesize("walk_curve", 0.8, seed=3), 30)  # a walk, then a second standing


def test_the_decoder_reads_the_clock_beside_the_code(clocked):
    config = clocked.bundle.codespace.config
    assert config.clock_conditions and config.still_seconds == CLOCK and config.condition_features == 2
    rows = len(config.memory_seconds) + 2 * len(config.resonator_hz) + len(HELD)
    assert config.held_seconds == HELD and config.memory.width == 64 * rows + len(CLOCK)
    first = clocked.bundle.codespace.decoder.net[0]
    assert first.in_features == clocked.bundle.codespace.quantizer.embedding_size + 2


@pytest.mark.parametrize("mode", ["regression", "detail"])
def test_its_stream_equals_its_causal_clip_through_a_stop(clocked, mode):
    motion = _stopping()
    causal = clocked.animate(motion, mode=mode, causal=True)
    stream = clocked.stream(mode=mode)
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal.vertices).max() <= 1e-5


def test_its_torch_crowd_equals_its_native_crowd_through_a_stop(clocked):
    rotations, roots = motion_to_poses(_stopping())
    native = clocked.crowd(mode="regression", device="native")
    device = clocked.crowd(mode="regression", device="cpu")
    worst = max(
        float(
            np.abs(
                device.push(rotations[t : t + 1], roots[t : t + 1])
                - native.push(rotations[t : t + 1], roots[t : t + 1])
            ).max()
        )
        for t in range(len(rotations))
    )
    assert worst < 1e-4, f"{worst * 1000:.3f} mm from the native crowd"


def test_its_onnx_graph_streams_as_the_python_stream_through_a_stop(clocked, tmp_path):
    pytest.importorskip("onnxruntime")
    pytest.importorskip("onnxscript")
    from hrr_garment.export.onnx_model import check_onnx, export_onnx

    written = export_onnx(clocked, tmp_path / "clocked.onnx", push_out=False)  # the clock acts before it
    gap = check_onnx(clocked, written.graph, _stopping())
    assert gap["max_mm"] < 0.1, f"ONNX departs from the Python stream by {gap['max_mm']:.4f} mm"
