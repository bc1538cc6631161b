"""The frame path (hrr_garment.inference.frame_path): every driver runs the same nine stages, and
each stage's output agrees across them: a clip animated causally, a stream, a crowd and the torch
step (the ONNX graph's module), stage by stage; and the run request: body, precision, device and
the exclusions are settings, old names still taken."""

import dataclasses
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from hrr_garment.inference import collision
from hrr_garment.inference.animator import Animator
from hrr_garment.inference.clip_path import animate_clip
from hrr_garment.inference.decoding import flush_denormals
from hrr_garment.inference.frame_path import STAGES, FramePath
from hrr_garment.inference.run_settings import RunSettings
from hrr_garment.motion.poses import motion_to_poses
from hrr_garment.motion.synth import synthesize

FIXTURE = Path(__file__).parents[1] / "fixtures" / "bundle-31b4ef9"


@pytest.fixture(scope="module")
def fixture_animator():
    return Animator.load(FIXTURE)


class Recorder:
    """Each stage's outputs, in the order they came (copies: a crowd reuses its arrays)."""

    def __init__(self):
        self.outputs = defaultdict(list)

    def __call__(self, stage: str, value) -> None:
        assert stage in STAGES, stage
        self.outputs[stage].append(np.array(value, copy=True))

    def clip(self) -> dict[str, np.ndarray]:
        """A clip driver's: one output per stage, frames first."""
        assert all(len(v) == 1 for v in self.outputs.values())
        return {k: v[0] for k, v in self.outputs.items()}

    def frames(self, row: int) -> dict[str, np.ndarray]:
        """A per-frame driver's, for the character in ``row``: (T, ...) per stage."""
        return {k: np.stack([frame[row] for frame in v]) for k, v in self.outputs.items()}


def _offline(animator, motion, **settings) -> dict[str, np.ndarray]:
    record = Recorder()
    run = animator.resolve(causal=True, **settings)
    with flush_denormals():
        animate_clip(FramePath(animator, run, observe=record), run.body.play(motion))
    return record.clip()


VERTEX_STAGES = ("decoding", "folds", "world", "push_out")
# a stream against the clip animated causally, in metres or the stage's own units: the features (each
# frame against its last, the memory carried) and the clip's (all at once) agree to rounding in
# float64, the window step takes the same float32 inputs and chooses the same bits; the mesh decoder
# batches a frame or a clip differently (float32 rounding), so the vertices agree to what
# tests/inference/test_stream.py holds them to
CAUSAL = {"features": 1e-12, "windows": 1e-12, "choice": 0.0, "blending": 0.0, "swing": 0.0} | dict.fromkeys(
    VERTEX_STAGES, 1e-5
)
# the torch step against the native crowd: FK and memory in float32 (features within 1e-5 of
# values up to about 6), then the same arithmetic; vertices as tests/export/test_onnx.py holds them
TORCH = {"features": 1e-4, "windows": 1e-4, "choice": 1e-5, "blending": 1e-5, "swing": 1e-5} | dict.fromkeys(
    VERTEX_STAGES, 1e-5
)


def _assert_stages_agree(ours: dict, theirs: dict, tolerances: dict, what: str) -> None:
    assert set(ours) == set(theirs) == set(STAGES), (what, sorted(ours), sorted(theirs))
    for stage in STAGES:
        a, b = ours[stage].astype(np.float64), theirs[stage].astype(np.float64)
        assert a.shape == b.shape, (what, stage, a.shape, b.shape)
        gap = np.abs(a - b).max()
        assert gap <= tolerances[stage], (
            f"{what}: stage {stage} departs by {gap:.3g}, over {tolerances[stage]:g}"
        )


@pytest.mark.parametrize("mode", ["hybrid", "detail"])
def test_every_stage_of_a_stream_and_a_crowd_equals_the_clip_animated_causally(fixture_animator, mode):
    """The offline causal clip, a stream of one and a crowd of two (another clip beside it) record
    each of the nine stages, and each stage's output is the clip's, frame by frame."""
    animator = fixture_animator
    walk, spin = synthesize("walk_curve", 1.0, seed=7), synthesize("spin", 1.0, seed=2)
    settings = {"mode": mode, "swing": 1.3}
    expected = {k: _offline(animator, m, **settings) for k, m in (("walk", walk), ("spin", spin))}
    if mode == "detail":  # the push-out takes its additions back on these clips: the drivers must agree
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(collision, "PUSH_OUT", dataclasses.replace(collision.PUSH_OUT, take_back=False))
            kept = _offline(animator, walk, **settings)["push_out"]
        assert np.abs(kept - expected["walk"]["push_out"]).max() > 1e-4
    stream = animator.stream(**settings)
    stream.crowd.path.observe = alone = Recorder()
    crowd = animator.crowd(device="native", **settings)
    crowd.path.observe = together = Recorder()
    for t in range(walk.num_frames):
        stream.push(walk.slice(t, t + 1))
        crowd.push_motions({"walk": walk.slice(t, t + 1), "spin": spin.slice(t, t + 1)})
    _assert_stages_agree(alone.frames(0), expected["walk"], CAUSAL, "stream")
    for row, key in enumerate(("walk", "spin")):
        _assert_stages_agree(together.frames(row), expected[key], CAUSAL, f"crowd {key}")
    # the same computation in the same order: a stream is a crowd of one, the same bits
    for stage in STAGES:
        assert np.array_equal(alone.frames(0)[stage], together.frames(0)[stage]), stage


def test_every_stage_of_the_torch_step_agrees_with_the_native_crowd(fixture_animator):
    """The torch step (ONNX's graph, a GPU crowd's; here on the CPU) re-implements the regression's
    stages in float32: each stage within its rounding of the native crowd's."""
    animator = fixture_animator
    motion = synthesize("walk_curve", 1.0, seed=7)
    quats, roots = motion_to_poses(motion)
    native = animator.crowd(mode="regression", device="native")
    native.path.observe = theirs = Recorder()
    device = animator.crowd(mode="regression", device="cpu")
    device.step.observe = ours = Recorder()
    for t in range(motion.num_frames):
        native.push(quats[t : t + 1], roots[t : t + 1])
        device.push(quats[t : t + 1], roots[t : t + 1])
    _assert_stages_agree(ours.frames(0), theirs.frames(0), TORCH, "torch step")


def test_the_run_request_carries_body_precision_device_and_exclusions(fixture_animator):
    """Body, precision, device and the exclusions are fields of the one settings object, keywords
    of every call alike; push_out is the switch's name and collision its old one, still taken;
    records keep reading the old name."""
    from hrr_garment.inference.resolved_run import recorded

    animator = fixture_animator
    motion = synthesize("walk", 0.5, seed=1)
    settings = RunSettings(mode="retrieval", collision=False, exclude_sequence=0, allow_outside=True)
    assert settings.push_out is False and settings == RunSettings(
        mode="retrieval", push_out=False, exclude_sequence=0, allow_outside=True
    )
    assert settings.replace(collision=True).push_out is True
    with pytest.raises(TypeError, match="old name of push_out"):
        RunSettings(collision=False, push_out=False)
    run = animator.resolve(settings)
    assert run.body.name == animator.body().name and run.exclude_sequence == 0 and run.precision == "float32"
    anim = animator.animate(motion, settings)
    assert (anim.match[:, 0] != 0).all()  # no window retrieved from the excluded sequence
    assert np.array_equal(
        anim.vertices,
        animator.animate(motion, mode="retrieval", collision=False, exclude_sequence=0).vertices,
    )
    assert recorded(anim.settings, "push_out") == 0 and recorded({"collision": 1}, "push_out") == 1
    with pytest.raises(ValueError, match="exclude_sequence must be a database sequence index"):
        animator.resolve(exclude_sequence=10**6)
    with pytest.raises(ValueError, match="precision must be one of"):
        RunSettings(precision="float16")
    # the animator's own settings: the request every call without a settings object starts from
    quiet = Animator(animator.bundle, mode="regression", push_out=False)
    assert quiet.resolve().mode == "regression" and not quiet.resolve().push_out
    assert quiet.crowd(device="native").run.device == "native"
    assert animator.crowd(mode="regression", device="cpu").run.device == "cpu"
