"""Splices (the legs of one training clip under the upper body of another, checked before simulation),
windows of training clips played backward and windows after which the body stops and stands."""

from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.body.self_contact import self_intersecting_frames
from hrr_garment.motion.io import save_motion
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.rotations import rotation_about_y
from hrr_garment.motion.skeleton import JOINT_INDEX
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.augment import (
    AUGMENT_PREFIXES,
    SpliceSettings,
    plan_backward,
    plan_splices,
    plan_stops,
    splice_candidates,
    window_candidates,
)
from hrr_garment.sim.plan import SequenceSpec, _file_pieces
from hrr_garment.sim.sources import clip_group


def _arms_through_the_chest(seconds: float) -> Motion:
    """A stand whose upper arms point across the chest (each turned 160 degrees about the vertical)."""
    clip = synthesize("idle", seconds, seed=0)
    local = np.array(clip.local_rotations)
    for side, sign in (("l", 1.0), ("r", -1.0)):
        local[:, JOINT_INDEX[f"{side}_shoulder"]] = rotation_about_y(
            np.asarray(sign * np.radians(160.0))
        ).astype(np.float32)
    return Motion(local, clip.root_translation, clip.fps, "arms through the chest")


@pytest.fixture
def library(tmp_path):
    """Bandai-style names: three contents in two styles, and a fourth whose arms pass through the body."""
    kinds = {"walk": "walk", "run": "run", "wave": "dance"}
    for i, (content, kind) in enumerate(kinds.items()):
        for style in ("proud", "sad"):
            save_motion(synthesize(kind, 3.0, seed=i), tmp_path / f"dataset-1_{content}_{style}_001.npz")
    save_motion(_arms_through_the_chest(3.0), tmp_path / "dataset-1_hug_proud_001.npz")
    return [spec for path in sorted(tmp_path.glob("*.npz")) for spec in _file_pieces(str(path), 1.0, None)]


def test_splices_mix_contents_and_refuse_limbs_through_the_body(library):
    assert self_intersecting_frames(_arms_through_the_chest(1.0)).any()  # the fixture's premise
    training = {s.name for s in library if "sad" not in s.name}  # the sad style held out
    options = SpliceSettings(count=10, seconds=2.0, arm_delay_s=0.2, seed=3)
    candidates = splice_candidates(library, training, options)
    assert {s.name for s in candidates} == training
    plan = plan_splices(candidates, options)
    assert len(plan.specs) == 10 and plan.refused > 0  # every draw with the hug's upper body is refused
    content = {s.path: clip_group(s.path.rsplit("/", 1)[-1][:-4], "content") for s in library}
    for spec in plan.specs:
        assert spec.name.startswith("splice_") and spec.stop - spec.start == 60
        assert content[spec.path] != content[spec.upper_path]  # a combination of two contents
        assert "sad" not in spec.path and "sad" not in spec.upper_path  # only training clips
        assert "hug" not in spec.upper_path
        assert not self_intersecting_frames(spec.motion()).any()
        assert abs(spec.arm_delay) <= 6
    assert any(s.arm_delay for s in plan.specs)
    # seeded: the same plan again (a re-run finds its splices simulated), and keys of their own
    assert plan_splices(candidates, options).specs == plan.specs
    assert len({s.key({}) for s in plan.specs}) == 10


def test_backward_windows_come_from_training_clips_whatever_their_names(library, tmp_path):
    """Windows played backward: from training clips only, the frames reversed, keys of their own,
    seeded; a file whose name lacks the splices' field (CMU's ``131_03``) is a clip like any other."""
    save_motion(synthesize("walk", 3.0, seed=9), tmp_path / "131_03.npz")
    cmu = _file_pieces(str(tmp_path / "131_03.npz"), 1.0, None)
    specs = library + cmu
    training = {s.name for s in specs if "sad" not in s.name}
    options = SpliceSettings(count=4, seconds=2.0, seed=3, backward=40)
    assert cmu[0] not in splice_candidates(specs, training, options)
    candidates = window_candidates(specs, training, options.seconds)
    assert {s.name for s in candidates} == training
    backward = plan_backward(candidates, options)
    assert [s.name for s in backward] == [f"backward_{i:03d}" for i in range(40)]
    assert any(s.path == cmu[0].path for s in backward)
    for spec in backward:
        assert spec.backward and spec.stop - spec.start == 60 and "sad" not in spec.path
        forward = SequenceSpec(spec.name, "file", path=spec.path, start=spec.start, stop=spec.stop)
        np.testing.assert_array_equal(spec.motion().local_rotations, forward.motion().local_rotations[::-1])
        assert spec.key({}) != forward.key({})  # simulated apart from the forward window
    assert plan_backward(candidates, options) == backward  # seeded
    assert (
        window_candidates(specs, training, 4.0) == [] and plan_backward([], options) == []
    )  # too short: none
    with pytest.raises(ValueError):
        SpliceSettings(backward=-1)


def test_stops_play_a_training_window_then_stand_still(library):
    """Each stop: a window of a training clip at its own speed, then its last pose held; seeded, keyed
    apart from the window alone and from another hold, drawn apart from the backward windows."""
    training = {s.name for s in library if "sad" not in s.name}
    options = SpliceSettings(seconds=2.0, backward=5, stops=12, stop_motion_s=1.5, stop_hold_s=2.0, seed=3)
    candidates = window_candidates(library, training, options.stop_motion_s)
    stops = plan_stops(candidates, options)
    assert [s.name for s in stops] == [f"stopstand_{i:03d}" for i in range(12)]
    assert len({(s.path, s.start) for s in stops}) > 1
    for spec in stops:
        assert "sad" not in spec.path and spec.stop - spec.start == 45 and spec.hold == 60
        assert spec.frames == 105
        motion = spec.motion()
        alone = SequenceSpec(spec.name, "file", path=spec.path, start=spec.start, stop=spec.stop)
        window = alone.motion()
        assert motion.num_frames == 105
        np.testing.assert_array_equal(motion.local_rotations[:45], window.local_rotations)
        np.testing.assert_array_equal(
            motion.root_translation[45:], np.repeat(window.root_translation[-1:], 60, 0)
        )
        assert np.abs(np.diff(motion.joint_positions[44:], axis=0)).max() < 1e-6  # it stands still
        assert spec.key({}) not in {alone.key({}), replace(alone, hold=30).key({})}
    assert plan_stops(candidates, options) == stops  # seeded
    # each kind drawn by a generator of its own: adding stops leaves the splices and the backward
    # windows (and their parts) as they were, and the stops do not depend on the others
    windows = window_candidates(library, training, options.seconds)
    alone = SpliceSettings(count=3, seconds=2.0, backward=5, seed=3)
    with_stops = replace(alone, stops=12, stop_motion_s=1.5, stop_hold_s=2.0)
    assert plan_backward(windows, with_stops) == plan_backward(windows, alone)
    mixed = splice_candidates(library, training, alone)
    assert plan_splices(mixed, with_stops).specs == plan_splices(mixed, alone).specs
    assert plan_stops(candidates, replace(options, count=0, backward=0)) == stops
    assert plan_stops([], options) == []
    with pytest.raises(ValueError):
        SpliceSettings(stops=-1)
    with pytest.raises(ValueError):
        SpliceSettings(stops=2, stop_hold_s=0.0)


def test_no_splice_without_two_contents(library):
    walks = [s for s in library if "_walk_" in s.name]
    assert plan_splices(walks, SpliceSettings(count=3, seconds=2.0)).specs == []
    assert (
        splice_candidates(library, {s.name for s in library}, SpliceSettings(count=3, seconds=4.0)) == []
    )  # too short
    with pytest.raises(ValueError):
        SpliceSettings(count=-1)
    assert isinstance(library[0], SequenceSpec)


@pytest.mark.sim
def test_a_build_adds_splices_of_training_clips_that_always_train(tmp_path, capsys):
    """hrr-simulate with a preset's ``splices``: the splices are simulated and train, their parts come
    from training clips only (no held-out style reaches training), and a re-run simulates nothing."""
    pytest.importorskip("newton", reason="the sim extra is not installed")
    from hrr_garment.cli.simulate import main as simulate_main
    from hrr_garment.data.dataset import GarmentDataset

    clips = tmp_path / "clips"
    clips.mkdir()
    for i, (content, kind) in enumerate({"walk": "walk", "run": "run", "wave": "dance"}.items()):
        for style in ("proud", "sad", "old"):
            save_motion(synthesize(kind, 1.2, seed=i), clips / f"dataset-1_{content}_{style}_001.npz")
    preset = tmp_path / "p.yaml"
    preset.write_text(
        "name: spliced\nvertices: 300\nseconds: 1.0\nsequences: {}\nmotions: [clips]\nsplit_by: style\n"
        "splits: {val: 0.2, test: 0.2}\nsim: {substeps: 10, iterations: 3, settle_s: 0.1}\n"
        "splices: {count: 2, seconds: 1.0, arm_delay_s: 0.1, backward: 1, stops: 1, stop_motion_s: 0.5, "
        "stop_hold_s: 0.5}\n"
    )
    out = tmp_path / "d.h5"
    args = [
        "--garment",
        "skirt",
        "--preset",
        str(preset),
        "--jobs",
        "1",
        "--no-preview",
        "--quiet",
        "-o",
        str(out),
    ]
    assert simulate_main(args) == 0
    ds = GarmentDataset(out)
    splices = sorted(n for n in ds.names if n.startswith("splice_"))
    assert splices == ["splice_000", "splice_001"] and set(splices) <= set(ds.splits["train"])
    assert "backward_000" in ds.splits["train"] and "backward_000" not in ds.splits["test"] + ds.splits["val"]
    held = {n.split("_")[2] for n in ds.splits["test"] + ds.splits["val"]}  # the held-out styles
    assert held and not held & {
        n.split("_")[2] for n in ds.splits["train"] if not n.startswith(AUGMENT_PREFIXES)
    }
    for name in splices:
        record = ds.sequence(name)
        assert record.motion.num_frames == 30 and record.garment.shape[0] == 30
        assert not any(style in record.motion.source for style in held)  # both parts from training styles
    backward = ds.sequence("backward_000").motion
    assert backward.num_frames == 30 and "played backward" in backward.source
    assert not any(style in backward.source for style in held)
    stop = ds.sequence("stopstand_000")
    assert (
        "stopstand_000" in ds.splits["train"] and stop.motion.num_frames == 30 and stop.garment.shape[0] == 30
    )
    assert np.abs(np.diff(stop.motion.root_translation[14:], axis=0)).max() == 0.0  # the body stands
    made = ds.info["summary"]["splices"]
    assert made["made"] == 2 and made["backward_made"] == 1 and made["stops_made"] == 1
    capsys.readouterr()
    assert simulate_main(args) == 0  # resumes: the same splices planned again, found simulated
    assert "13 reused, 0 simulated now" in capsys.readouterr().out
