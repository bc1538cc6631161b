"""A model trained across cloths: it reads each sequence's cloth, records the range of its training
cloths and refuses a cloth outside it, animates offline, in a crowd and from the command line in
the cloth asked for, and records it; a model of one cloth keeps its networks and its training key."""

import json

import numpy as np
import pytest

from hrr_garment.garment.fabrics import FABRICS
from hrr_garment.garment.material import parse_material
from hrr_garment.garment.material_range import MATERIAL_FEATURES, MaterialRange, material_vector
from hrr_garment.motion.synth import synthesize
from tests.conftest import TINY_TRAINING, assert_crowd_streams_as_alone, three_clips, train_tiny

LIGHT, STIFF = FABRICS["jersey"], FABRICS["cotton-twill"]


@pytest.fixture(scope="module")
def materials_model(tmp_path_factory):
    """A tiny skirt model trained on the simulator-free dataset, its sequences in turn in jersey and
    cotton twill (training: jersey, twill, jersey): (its folder, the dataset)."""
    from hrr_garment.data.synthetic import write_synthetic_dataset
    from hrr_garment.garment.templates import make_garment

    root = tmp_path_factory.mktemp("materials")
    data = write_synthetic_dataset(root / "skirt.h5", make_garment("skirt", 300), materials=[LIGHT, STIFF])
    (root / "cfg.yaml").write_text(TINY_TRAINING)
    train_tiny(data, root / "model", root / "cfg.yaml")
    return root / "model", data


def test_a_cloth_is_read_as_the_logarithms_of_its_values_and_its_damping():
    vector = material_vector(LIGHT)
    assert vector.shape == (len(MATERIAL_FEATURES),)
    assert np.allclose(10.0 ** vector[:4], [LIGHT.density, LIGHT.stretch, LIGHT.shear, LIGHT.bend], rtol=1e-5)
    assert vector[4] == pytest.approx(LIGHT.damping)
    known = MaterialRange.of([material_vector(LIGHT), material_vector(STIFF)])
    assert known.cloths == 2 and MaterialRange.from_dict(known.to_dict()) == known
    assert known.outside(material_vector(LIGHT)) == [] and known.outside(material_vector(STIFF)) == []
    # denim is heavier than either and shears stiffer; its stretch and bending, between theirs, are not named
    assert known.outside(material_vector(FABRICS["denim"])) == [
        "density 0.324 kg/m^2, trained on 0.187-0.22 kg/m^2",
        "shear 17.4 N/m, trained on 6.9-10.1 N/m",
    ]
    with pytest.raises(ValueError, match="lows lie at or below"):
        MaterialRange.from_dict({**known.to_dict(), "low": list(known.high), "high": list(known.low)})


def test_a_model_across_cloths_reads_each_sequences_cloth_and_records_their_range(materials_model):
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.inference.animator import Animator

    folder, data = materials_model
    meta = json.loads((folder / "bundle.json").read_text())
    assert meta["codespace"]["config"]["material_features"] == len(MATERIAL_FEATURES)
    assert meta["codespace"]["config"]["body_features"] == 0  # one body
    assert meta["materials"]["range"]["cloths"] == 2
    animator = Animator.load(folder)
    # the project's default cloth (0.15 kg/m^2) is lighter than both: the default is one of the two
    assert animator.bundle.default_material.name in ("jersey", "cotton-twill")
    ds = GarmentDataset(data)
    assert [ds.material_of(n).name for n in ds.splits["train"]] == ["jersey", "cotton-twill", "jersey"]
    motion = synthesize("walk", 0.5, seed=0)
    between = parse_material("jersey,bend=1.5e-5")  # a cloth between them, never trained in
    for cloth in (LIGHT, STIFF, between):
        feats = animator.features(motion, material=cloth)
        assert np.allclose(feats[:, -len(MATERIAL_FEATURES) :], material_vector(cloth))


def test_the_cloth_reaches_the_decoder_and_is_recorded(materials_model, tmp_path):
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.inference.animator import Animator

    folder, _ = materials_model
    animator = Animator.load(folder)
    motion = synthesize("walk", 1.0, seed=4)
    light = animator.animate(motion, mode="regression", material="jersey", push_out=False)
    stiff = animator.animate(motion, mode="regression", material=STIFF, push_out=False)
    assert np.abs(light.vertices - stiff.vertices).max() > 1e-4  # another cloth, other cloth
    assert light.material == LIGHT and stiff.material == STIFF
    light.save(tmp_path / "light.h5")
    assert read_animation_h5(tmp_path / "light.h5").material == LIGHT
    gl = pytest.importorskip("pygltflib")
    from hrr_garment.export.glb import write_glb

    glb = write_glb(read_animation_h5(tmp_path / "light.h5"), tmp_path / "light.glb").path
    assert gl.GLTF2().load(str(glb)).extras["cloth"] == LIGHT.to_dict()  # the export records the cloth


def test_hrr_preview_draws_one_clip_in_two_cloths_side_by_side(materials_model, tmp_path):
    from PIL import Image

    from hrr_garment.cli.preview import main
    from hrr_garment.inference.animator import Animator

    folder, _ = materials_model
    animator = Animator.load(folder)
    motion = synthesize("walk", 0.5, seed=4)
    for cloth in ("jersey", "cotton-twill"):
        animator.animate(motion, material=cloth).save(tmp_path / f"{cloth}.h5")
    args = [str(tmp_path / "jersey.h5"), "--frames", "1", "--size", "64", "--views", "front"]
    assert main([*args, "-o", str(tmp_path / "one.png")]) == 0
    assert main([*args, "--beside", str(tmp_path / "cotton-twill.h5"), "-o", str(tmp_path / "two.png")]) == 0
    one, two = Image.open(tmp_path / "one.png"), Image.open(tmp_path / "two.png")
    assert two.size == (2 * one.width, one.height) == (128, 64)
    left = np.asarray(two)[:, :64].astype(int)
    assert np.abs(left - np.asarray(one).astype(int)).max() == 0  # the first clip drawn as alone


def test_a_cloth_unlike_the_training_cloths_is_refused_or_warned_about(materials_model):
    from hrr_garment.errors import InputError
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.run_material import MaterialOutsideRange

    folder, _ = materials_model
    animator = Animator.load(folder)
    motion = synthesize("walk", 0.5, seed=0)
    with pytest.raises(MaterialOutsideRange, match=r"cloth 'denim' is unlike the 2 cloths .* density 0.324"):
        animator.animate(motion, material="denim")
    with pytest.warns(UserWarning, match="animating it anyway"):
        anim = animator.animate(motion, material="denim", allow_outside_material=True)
    assert np.isfinite(anim.vertices).all()
    with pytest.raises(InputError, match="unknown material value"):
        animator.animate(motion, material="jersey,weight=3")


def test_a_model_of_one_cloth_keeps_its_networks_and_refuses_another_cloth(trained):
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.run_material import MaterialOutsideRange

    root, _, _ = trained
    meta = json.loads((root / "model" / "bundle.json").read_text())
    assert "material_features" not in meta["codespace"]["config"]  # its settings as before cloths
    assert meta["materials"]["range"]["cloths"] == 1 and meta["materials"]["default"]["name"] == "default"
    animator = Animator.load(root / "model")
    motion = synthesize("walk", 0.5, seed=0)
    assert animator.animate(motion, material="default").material == FABRICS["default"]
    with pytest.raises(MaterialOutsideRange, match="unlike the 1 cloth the model.*train across cloths"):
        animator.animate(motion, material="denim")


def test_a_crowd_of_characters_in_different_cloths_equals_each_one_alone_in_its_cloth(materials_model):
    """One batched step for characters in three cloths (two set with set_material, one the run's):
    each one's frames equal its offline causal animation in its cloth."""
    from hrr_garment.inference.animator import Animator

    folder, _ = materials_model
    animator = Animator.load(folder)
    cloths = {"a": LIGHT, "b": "cotton-twill,bend=2e-5", "c": None}
    clips = three_clips()
    alone = {k: animator.animate(clips[k], material=cloths[k], causal=True).vertices for k in clips}
    crowd = animator.crowd()
    for k in ("a", "b"):
        crowd.set_material(k, cloths[k])
    assert_crowd_streams_as_alone(crowd, clips, alone)
    # the regression as one torch step (a GPU's crowd, here on the CPU): each character's cloth an input
    regression = {
        k: animator.animate(clips[k], material=cloths[k], causal=True, mode="regression").vertices
        for k in clips
    }
    device = animator.crowd(mode="regression", device="cpu")
    for k in ("a", "b"):
        device.set_material(k, cloths[k])
    assert_crowd_streams_as_alone(device, clips, regression)


def test_hrr_animate_takes_a_cloth_and_refuses_one_outside_the_range(materials_model, tmp_path, capsys):
    from hrr_garment.cli.animate import main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.motion.io import save_motion

    folder, _ = materials_model
    save_motion(synthesize("walk", 1.0, seed=2), tmp_path / "clip.npz")
    out = tmp_path / "out.h5"
    common = [str(tmp_path / "clip.npz"), "--model", str(folder), "-o", str(out)]
    assert main([*common, "--material", "jersey,bend=7e-6"]) == 0
    assert "in jersey+bend (density 0.187 kg/m^2" in capsys.readouterr().out
    assert read_animation_h5(out).material.bend == pytest.approx(7e-6)
    out.unlink()
    assert main([*common, "--material", "denim"]) != 0
    err = capsys.readouterr().err
    assert "denim" in err and "density 0.324 kg/m^2, trained on 0.187-0.22" in err
    assert not out.exists()  # nothing written


def test_the_unseen_materials_protocol_sets_the_model_beside_a_specialist(
    materials_model, trained, tmp_path, capsys
):
    """hrr-eval --unseen-material: a cloth between jersey and twill, which the model never trained
    in, beside a model of one cloth as the reference; the training cloths and a cloth outside the
    range are refused."""
    from hrr_garment.cli.eval import main
    from hrr_garment.data.synthetic import write_synthetic_dataset
    from hrr_garment.garment.templates import make_garment

    folder, data = materials_model
    root, _, _ = trained
    between = parse_material("density=0.2,stretch=600,shear=8,bend=1.3e-5")
    unseen = write_synthetic_dataset(tmp_path / "between.h5", make_garment("skirt", 300), materials=[between])
    heavy = write_synthetic_dataset(
        tmp_path / "denim.h5", make_garment("skirt", 300), materials=[FABRICS["denim"]]
    )
    common = ["--model", str(folder), "--dataset", str(data), "--modes", "regression", "--no-sweep"]
    common += ["--library", "0", "--ensemble", "0", "--no-plots", "--quiet"]
    with pytest.warns(UserWarning, match="unlike the 1 cloth"):  # the reference: a model of the default cloth
        assert (
            main([*common, "--unseen-material", f"{unseen}={root / 'model'}", "-o", str(tmp_path / "r")]) == 0
        )
    section = json.loads((tmp_path / "r" / "report.json").read_text())["unseen_materials"]["between"]
    assert section["cloth"] == between.name and section["sequences"] == ["run_000"]
    assert section["model"]["pve_mm"] > 0 and section["specialist"]["pve_mm"] > 0
    assert "## Unseen cloths" in (tmp_path / "r" / "report.md").read_text()
    assert main([*common, "--unseen-material", str(data), "-o", str(tmp_path / "again")]) != 0  # trained in
    assert main([*common, "--unseen-material", str(heavy), "-o", str(tmp_path / "heavy")]) != 0  # outside
    # the cloth's data simulated otherwise than the model's (here with the cloth's viscosity): its
    # truth is another solver's, and the comparison is refused naming the setting
    import h5py

    with h5py.File(unseen, "r+") as f:
        f.attrs["info"] = json.dumps({**json.loads(f.attrs["info"]), "sim": {"cloth_viscosity": 0.02}})
    assert main([*common, "--unseen-material", str(unseen), "-o", str(tmp_path / "viscous")]) != 0
    assert "cloth_viscosity 0.02 (the model's data: None)" in capsys.readouterr().err


def test_the_onnx_step_takes_each_characters_cloth_as_an_input(materials_model, tmp_path):
    """A model across cloths' graph has a material input: fed a cloth, it streams as the Python stream
    in that cloth; a cloth outside the model's range is refused by the runner."""
    pytest.importorskip("onnxruntime")
    from hrr_garment.errors import InputError
    from hrr_garment.export.onnx_model import MATERIAL, OnnxStream, export_onnx
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.poses import motion_to_poses

    folder, _ = materials_model
    animator = Animator.load(folder)
    # no push-out (the graphs of tests/export/test_onnx.py hold it): the cloth enters before it
    written = export_onnx(animator, tmp_path / "skirt.onnx", material="jersey", push_out=False)
    motion = synthesize("walk_curve", 0.6, seed=3)
    quats, roots = motion_to_poses(motion)
    for cloth in ("jersey", "cotton-twill,bend=2e-5"):
        graph = OnnxStream(written.graph, material=cloth)
        assert MATERIAL in [i.name for i in graph.session.get_inputs()]
        stream = animator.stream(mode="regression", material=cloth, push_out=False)
        for t in range(motion.num_frames):
            ours = graph.push(quats[t : t + 1], roots[t : t + 1])[0]
            assert np.abs(ours - stream.push(rotation=quats[t], root=roots[t])).max() < 1e-4, (cloth, t)
    with pytest.raises(InputError, match="outside its model's range"):
        OnnxStream(written.graph, material="denim")
