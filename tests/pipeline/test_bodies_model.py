"""A model trained across bodies: it reads each body's measures, records the range of its training
bodies and refuses a body outside it, stands the garment on the body it animates, and streams on
a body as it animates offline; a model of one body keeps the networks it had before bodies."""

import json

import h5py
import numpy as np
import pytest

from hrr_garment.body.body_file import BodyRecord, write_body
from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.body.measures import BODY_MEASURES, BodyRange, body_vector
from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.garment.dressing import DressedBody
from hrr_garment.garment.templates import make_garment
from hrr_garment.garment.transfer import transfer_garment
from hrr_garment.motion.frame import to_body_frame
from hrr_garment.motion.poses import motion_to_poses
from hrr_garment.motion.synth import synthesize
from tests.conftest import TINY_TRAINING, assert_crowd_streams_as_alone, three_clips, train_tiny
from tests.garment.test_templates_on_bodies import _larger_body


def _record(scale: float, fuller: float = 1.0) -> BodyRecord:
    body = _larger_body(scale, fuller)
    return BodyRecord(body.skeleton, body, body.pelvis_height, stature=1.7 * scale)


def _dressed(garment, name: str, scale: float, fuller: float = 1.0) -> DressedBody:
    record = _record(scale, fuller)
    return DressedBody(name, record, transfer_garment(garment, made_for=DEFAULT_BODY, body=record.body)[0])


@pytest.fixture(scope="module")
def bodies_model(tmp_path_factory):
    """A tiny skirt model trained on the simulator-free dataset on two bodies, 1.1 and 0.92 times
    the mannequin: (its folder, the dataset)."""
    from hrr_garment.data.synthetic import write_synthetic_dataset

    root = tmp_path_factory.mktemp("bodies")
    garment = make_garment("skirt", 300)
    bodies = [_dressed(garment, "tall", 1.1, 1.1), _dressed(garment, "short", 0.92, 0.95)]
    data = write_synthetic_dataset(root / "skirt.h5", garment, bodies=bodies)
    (root / "cfg.yaml").write_text(TINY_TRAINING)
    train_tiny(data, root / "model", root / "cfg.yaml")
    return root / "model", data


def test_a_uniformly_larger_body_measures_larger_by_the_same_factor():
    """Every measure is a length: bones k times longer with k times the radii measure k times more."""
    base = body_vector(_record(1.0))
    assert np.allclose(body_vector(_record(1.2, 1.2)), 1.2 * base, rtol=0.02)
    assert np.allclose(body_vector(mannequin_record())[:2], [1.70, 0.96])
    known = BodyRange.of([body_vector(_record(0.95)), body_vector(_record(1.1))])
    assert known.outside(body_vector(_record(1.0))) == []
    outside = known.outside(body_vector(_record(1.3)))
    assert outside and outside[0].startswith("stature 2.210 m, trained on")


def test_models_learn_each_frame_less_its_bodys_rest_offset(bodies_model):
    """The autoencoder's frames: the body frame less the offset of the sequence's own body, which
    stands the garment on the mannequin's rest shape at rest."""
    from hrr_garment.train.training_frames import body_frames

    _, data = bodies_model
    ds = GarmentDataset(data)
    for name in ("walk_000", "walk_001"):
        rec = ds.sequence(name)
        dressed = ds.bodies[ds.body_name_of[name]]
        frames = to_body_frame(rec.garment.astype(np.float64), rec.motion)
        assert np.allclose(body_frames(ds, [name]), frames - dressed.offset(ds.template), atol=1e-5)
        assert np.abs(dressed.offset(ds.template)).max() > 0.02  # a body unlike the mannequin
    assert np.abs(ds.bodies["mannequin"].offset(ds.template)).max() == 0.0


def test_a_model_across_bodies_reads_their_measures_and_records_their_range(bodies_model):
    from hrr_garment.inference.animator import Animator

    folder, data = bodies_model
    meta = json.loads((folder / "bundle.json").read_text())
    assert meta["codespace"]["config"]["body_features"] == len(BODY_MEASURES)
    assert meta["bodies"]["range"]["bodies"] == 2 and meta["bodies"]["default"] is None
    animator = Animator.load(folder)
    ds = GarmentDataset(data)
    tall = ds.bodies["tall"].record
    feats = animator.features(synthesize("walk", 0.5, seed=0), body=animator.body(tall))
    assert np.allclose(feats[:, -len(BODY_MEASURES) :], body_vector(tall))  # every frame carries the body


def test_the_garment_stands_on_the_body_it_is_animated_on(bodies_model):
    """The waist rides as much higher on the tall body than on the short one as their rest shapes
    put it (the model predicts the garment relative to its body at rest); the push-out and the
    exported capsules are that body's."""
    from hrr_garment.inference.animator import Animator

    folder, data = bodies_model
    ds = GarmentDataset(data)
    animator = Animator.load(folder)
    motion = synthesize("idle", 1.0, seed=0)
    waist, rest = {}, {}
    for name in ("tall", "short"):
        anim = animator.animate(motion, body=ds.bodies[name], mode="regression")
        assert anim.body_name == name and np.allclose(anim.radii, ds.bodies[name].body.radii)
        waist[name] = anim.vertices[:, :, 1].max(1).mean()
        rest[name] = ds.bodies[name].garment.vertices[:, 1].max()
        assert abs(waist[name] - rest[name]) < 0.05  # near its own rest height (the idle pelvis bobs)
    assert rest["tall"] - rest["short"] > 0.15
    assert abs((waist["tall"] - waist["short"]) - (rest["tall"] - rest["short"])) < 0.02


def test_a_body_unlike_the_training_bodies_is_refused_or_warned_about(bodies_model):
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.character_body import BodyOutsideRange

    folder, _ = bodies_model
    animator = Animator.load(folder)
    giant = _record(1.4)
    with pytest.raises(BodyOutsideRange, match="stature 2.380 m, trained on 1.564-1.870 m"):
        animator.animate(synthesize("walk", 0.5, seed=0), body=giant)
    with pytest.warns(UserWarning, match="animating it anyway"):
        anim = animator.animate(synthesize("walk", 0.5, seed=0), body=giant, allow_outside=True)
    assert np.isfinite(anim.vertices).all()


def test_a_model_of_the_mannequin_alone_keeps_its_networks_and_refuses_other_bodies(trained):
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.character_body import BodyOutsideRange

    root, _, _ = trained
    meta = json.loads((root / "model" / "bundle.json").read_text())
    assert meta["codespace"]["config"]["body_features"] == 0 and "bodies" not in meta
    animator = Animator.load(root / "model")
    assert animator.bundle.body_range.bodies == 1
    with pytest.raises(BodyOutsideRange, match="unlike the 1 body the model"):
        animator.body(_record(1.1))


def test_a_stream_on_a_body_equals_the_offline_causal_animation_on_it(bodies_model):
    from hrr_garment.inference.animator import Animator

    folder, data = bodies_model
    animator = Animator.load(folder)
    short = GarmentDataset(data).bodies["short"].record
    motion = synthesize("walk_curve", 1.0, seed=3)
    causal = animator.animate(motion, body=short, causal=True).vertices
    stream = animator.stream(body=short)
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal).max() <= 1e-5


def test_the_onnx_step_on_a_body_streams_as_the_python_stream_on_it(bodies_model, tmp_path, capsys):
    """hrr-export-model --onnx --body: the graph reads the body's measures, plays the poses on its
    skeleton, stands the garment on it and pushes out of its capsules, as the Python stream does."""
    pytest.importorskip("onnxruntime")
    from hrr_garment.cli.export_model import main
    from hrr_garment.export.onnx_model import OnnxStream
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.io import save_motion

    folder, data = bodies_model
    short = GarmentDataset(data).bodies["short"].record
    write_body(tmp_path / "short.json", short)
    motion = synthesize("walk_curve", 1.0, seed=3)
    save_motion(motion, tmp_path / "clip.npz")
    assert (
        main(
            [
                "--model",
                str(folder),
                "--onnx",
                "-o",
                str(tmp_path / "short.onnx"),
                "--body",
                str(tmp_path / "short.json"),
                "--check",
                str(tmp_path / "clip.npz"),
            ]
        )
        == 0
    )
    # the terms of the motion it learned from travel with the graph (here procedural: it may ship)
    assert "motion licence: may ship commercially" in capsys.readouterr().out
    graph = OnnxStream(tmp_path / "short.onnx")
    assert graph.session.get_modelmeta().custom_metadata_map["commercial_use"] == "true"
    stream = Animator.load(folder).stream(mode="regression", body=short)
    for t in range(motion.num_frames):
        ours = graph.push(motion_to_poses(motion.slice(t, t + 1))[0], motion.root_translation[t : t + 1])[0]
        assert np.abs(ours - stream.push(motion.slice(t, t + 1))).max() < 1e-5, t


def test_hrr_animate_on_a_body_file(bodies_model, tmp_path, capsys):
    from hrr_garment.cli.animate import main

    folder, data = bodies_model
    from hrr_garment.motion.io import save_motion

    save_motion(synthesize("walk", 1.0, seed=2), tmp_path / "clip.npz")
    write_body(tmp_path / "short.json", GarmentDataset(data).bodies["short"].record)
    assert (
        main(
            [
                str(tmp_path / "clip.npz"),
                "-o",
                str(tmp_path / "out.h5"),
                "--model",
                str(folder),
                "--body",
                str(tmp_path / "short.json"),
            ]
        )
        == 0
    )
    assert "on body short" in capsys.readouterr().out
    with h5py.File(tmp_path / "out.h5") as f:
        assert f.attrs["body_name"] == "short"
    write_body(tmp_path / "giant.json", _record(1.4))
    assert (
        main(
            [
                str(tmp_path / "clip.npz"),
                "-o",
                str(tmp_path / "giant.h5"),
                "--model",
                str(folder),
                "--body",
                str(tmp_path / "giant.json"),
            ]
        )
        != 0
    )
    err = capsys.readouterr().err
    assert "giant.json" in err and "unlike the 2 bodies" in err and not (tmp_path / "giant.h5").exists()


def test_hrr_body_info_says_whether_a_body_is_within_a_models_range(bodies_model, tmp_path, capsys):
    """The check before simulating a held-out body: within the range exits 0, outside 1 naming the
    measures."""
    from hrr_garment.cli.body import main

    folder, data = bodies_model
    write_body(tmp_path / "short.json", GarmentDataset(data).bodies["short"].record)
    write_body(tmp_path / "between.json", _record(1.0, 1.0))
    write_body(tmp_path / "giant.json", _record(1.4))
    for name in ("short", "between"):
        assert main(["info", str(tmp_path / f"{name}.json"), "--model", str(folder)]) == 0
        assert "within the range of the 2 bodies" in capsys.readouterr().out
    assert main(["info", str(tmp_path / "giant.json"), "--model", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "outside the range of the 2 bodies" in out and "stature 2.380 m" in out
    assert main(["info", str(tmp_path / "giant.json"), "--model", str(folder), "--json"]) == 1
    info = json.loads(capsys.readouterr().out)
    assert info["model"]["training_bodies"] == 2 and any(
        line.startswith("stature") for line in info["model"]["outside"]
    )


def test_hrr_body_info_inside_asks_the_model_how_much_cloth_goes_inside_the_body(
    bodies_model, tmp_path, capsys
):
    """``--inside``: the cloth inside the body and inside the model's own before the push-out, on the
    check's walk, as :func:`cloth_inside` measures it; without ``--model`` a clear refusal."""
    from hrr_garment.cli.body import main
    from hrr_garment.eval.inside_body import check_motion, cloth_inside
    from hrr_garment.inference.animator import Animator

    folder, data = bodies_model
    record = GarmentDataset(data).bodies["short"].record
    write_body(tmp_path / "short.json", record)
    assert main(["info", str(tmp_path / "short.json"), "--model", str(folder), "--inside", "--json"]) == 0
    inside = json.loads(capsys.readouterr().out)["model"]["inside_before_push_out"]
    animator = Animator.load(folder)
    own, short = cloth_inside(animator, check_motion()), cloth_inside(animator, check_motion(), record)
    assert inside["the model's own body"]["inside_pct"] == pytest.approx(own.inside_pct)
    assert inside["body 'short'"]["inside_any_pct"] == pytest.approx(short.inside_any_pct)
    # a body scaled from the mannequin has no mesh: its capsules are the body the viewer sees
    assert inside["body 'short'"]["visible_body"] == "capsules" == own.visible_body
    assert short.inside_visible_pct == pytest.approx(short.inside_pct, rel=1e-12, abs=1e-12)
    assert (
        inside["body 'short'"]["stature_m"] == pytest.approx(record.stature) != pytest.approx(own.stature_m)
    )
    assert main(["info", str(tmp_path / "short.json"), "--model", str(folder), "--inside"]) == 0
    assert "inside body 'short' before the push-out" in capsys.readouterr().out
    assert main(["info", str(tmp_path / "short.json"), "--inside"]) != 0
    assert "--inside asks a model" in capsys.readouterr().err


def test_a_crowd_of_characters_on_different_bodies_equals_each_one_alone_on_its_body(bodies_model):
    """One batched step for characters of three bodies (two set with set_body, one the crowd's own):
    each one's frames equal its offline causal animation on its body."""
    from hrr_garment.inference.animator import Animator

    folder, data = bodies_model
    animator = Animator.load(folder)
    ds = GarmentDataset(data)
    bodies = {"a": ds.bodies["tall"].record, "b": ds.bodies["short"].record, "c": None}
    clips = three_clips()
    alone = {k: animator.animate(clips[k], body=bodies[k], causal=True).vertices for k in clips}
    crowd = animator.crowd()
    for k in ("a", "b"):
        crowd.set_body(k, bodies[k])
    assert_crowd_streams_as_alone(crowd, clips, alone)


def test_the_unseen_bodies_protocol_sets_the_model_beside_a_specialist(bodies_model, trained, tmp_path):
    """hrr-eval --unseen-body: the mannequin, which the model across the tall and short bodies never
    saw, with the tiny mannequin model as its specialist; a dataset on a training body is refused."""
    from hrr_garment.cli.eval import main

    folder, data = bodies_model
    root, mannequin_data, _ = trained
    common = [
        "--model",
        str(folder),
        "--dataset",
        str(data),
        "--modes",
        "regression",
        "--no-sweep",
        "--library",
        "0",
        "--ensemble",
        "0",
        "--no-plots",
        "--quiet",
    ]
    assert (
        main([*common, "--unseen-body", f"{mannequin_data}={root / 'model'}", "-o", str(tmp_path / "report")])
        == 0
    )
    section = json.loads((tmp_path / "report" / "report.json").read_text())["unseen_bodies"][
        mannequin_data.stem
    ]
    assert section["body"] == "mannequin" and section["sequences"] == ["run_000"]
    assert section["model"]["pve_mm"] > 0 and section["specialist"]["pve_mm"] > 0
    assert "## Unseen bodies" in (tmp_path / "report" / "report.md").read_text()
    assert section["model"]["visible_bodies"] == {"capsules": 1}  # the mannequin's visible body
    assert section["model"]["inside_visible_before_pct"] == pytest.approx(
        section["model"]["penetration_before_pct"], abs=1e-9
    )
    assert (
        main([*common, "--unseen-body", str(data), "-o", str(tmp_path / "again")]) != 0
    )  # tall and short: trained on


def test_the_auto_calibration_measures_the_default_bodys_clips_apart(bodies_model, tmp_path):
    """Validation clips on the mannequin (the default body) and on another body: every candidate
    also carries its PVE on the mannequin's clips alone, what calibrating on those alone measures;
    a validation on one body carries none."""
    from hrr_garment.data.synthetic import write_synthetic_dataset
    from hrr_garment.eval.auto_criterion import DEFAULT_BODY_PVE
    from hrr_garment.eval.auto_mode import calibrate_auto_mode
    from hrr_garment.inference.animator import Animator

    folder, data = bodies_model
    animator = Animator.load(folder)
    on_body = GarmentDataset(data).sequence("walk_002")
    on_mannequin = GarmentDataset(
        write_synthetic_dataset(tmp_path / "m.h5", make_garment("skirt", 300))
    ).sequence("run_000")
    assert on_body.body_name != on_mannequin.body_name == "mannequin"
    mixed = calibrate_auto_mode(animator, [on_body, on_mannequin], progress=False)
    alone = calibrate_auto_mode(animator, [on_mannequin], progress=False)
    assert mixed.default_body_sequences == 1 and alone.default_body_sequences == 0
    for label, c in alone.candidates.items():
        assert DEFAULT_BODY_PVE not in c
        if label in mixed.candidates:
            assert mixed.candidates[label][DEFAULT_BODY_PVE] == pytest.approx(c["pve_mm"])
    assert all(DEFAULT_BODY_PVE in c for c in mixed.candidates.values())
    assert mixed.candidates["hybrid"]["pve_mm"] != pytest.approx(alone.candidates["hybrid"]["pve_mm"])


def test_simulated_protocols_stand_their_truths_on_the_datasets_own_body(bodies_model, trained, tmp_path):
    """A dataset of one body other than the mannequin (a character's, an anny body's) has hrr-eval's
    simulated truths (--motions, the library protocol) on that body, as its model was trained; one
    across bodies, or of the mannequin, on the mannequin."""
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.data.synthetic import write_synthetic_dataset
    from hrr_garment.eval.protocols import own_body

    garment = make_garment("skirt", 300)
    one = write_synthetic_dataset(tmp_path / "one.h5", garment, bodies=[_dressed(garment, "tall", 1.1, 1.1)])
    body = own_body(GarmentDataset(one))
    assert body is not None and body.name == "tall" and body.record.stature == pytest.approx(1.87)
    assert own_body(GarmentDataset(bodies_model[1])) is None  # tall and short: the mannequin, their default
    assert own_body(GarmentDataset(trained[1])) is None
