"""Data across materials: a preset's ``materials`` section gives each sequence its cloth (named fabrics
and cloths drawn over their span), the part keys and the dataset follow it, splits hold out whole
cloths, and a build simulates each sequence in its own cloth."""

import math

import numpy as np
import pytest

from hrr_garment.errors import InputError
from hrr_garment.garment.fabrics import FABRICS
from hrr_garment.sim.material_plan import DRAWN, MaterialPlan, choose_materials, drawn_materials
from hrr_garment.sim.plan import SequenceSpec, clip_name, in_material, on_body
from hrr_garment.sim.preset import CONFIG_DIR


@pytest.mark.parametrize(
    ("section", "phrase"),
    [
        ({"fabrics": ["velvet"]}, "unknown fabric 'velvet'"),
        ({"fabrics": ["denim"], "colour": "red"}, "unknown keys"),
        ({"fabrics": ["denim", "jersey"], "per_clip": 3}, "per_clip must be 1-2"),
        ({"fabrics": ["denim", "denim"]}, "each fabric once"),
        ({"fabrics": "denim"}, "a list of fabric names"),
        ({"count": 2, "hold_out": "false"}, "hold_out must be true, false or a list"),
        ({"fabrics": ["denim", "jersey"], "hold_out": ["silk"]}, r"hold_out names \['silk'\], not among"),
        ({"fabrics": ["denim", "jersey"], "hold_out": ["denim", "jersey"]}, "leave at least one to train"),
        ({"fabrics": ["denim"], "count": 2.7}, "count must be whole numbers"),
        ("denim", "a mapping"),
    ],
)
def test_a_bad_materials_section_is_refused_naming_the_preset(section, phrase):
    with pytest.raises(InputError, match=phrase) as err:
        MaterialPlan.from_preset(section, "mine.yaml")
    assert "mine.yaml" in str(err.value)


def test_drawn_cloths_spread_log_uniformly_over_the_fabrics_span():
    """Each drawn value lies within the named fabrics' span, one draw in each of ``count`` equal
    slices of its log range (a Latin hypercube), the same for the same seed."""
    plan = MaterialPlan(fabrics=("denim", "jersey", "polyester"), count=6, seed=3)
    drawn = drawn_materials(plan)
    assert [m.name for m in drawn] == [f"cloth{k:02d}" for k in range(6)]
    assert drawn == drawn_materials(plan) and drawn != drawn_materials(MaterialPlan(plan.fabrics, 6, seed=4))
    named = [FABRICS[n] for n in plan.fabrics]
    for key in DRAWN:
        low, high = (math.log(f(getattr(m, key) for m in named)) for f in (min, max))
        where = (np.log([getattr(m, key) for m in drawn]) - low) / (high - low)
        assert sorted(np.floor(where * 6).astype(int).tolist()) == list(range(6)), key
    assert all(m.damping == FABRICS["default"].damping for m in drawn)


def test_each_clip_goes_to_per_clip_cloths_in_turn_and_splits_with_its_clip():
    """Two cloths a clip: ``CLIP__CLOTH`` sequences, every cloth as often as another, a clip's
    copies sharing their clip's name (so its split group); a clip on a body as well strips both."""
    specs = [SequenceSpec(f"walk_{i:03d}", "walk", seed=i, seconds=1.0) for i in range(6)]
    choice = choose_materials(specs, {"fabrics": ["denim", "jersey", "default"], "per_clip": 2}, "p")
    assert len(choice.specs) == 12 and set(choice.materials) == {"denim", "jersey", "default"}
    assert choice.hold_out and choice.info["cloths"]["denim"]["density"] == FABRICS["denim"].density
    counts = {}
    for spec in choice.specs:
        assert spec.name == in_material(clip_name(spec), spec.material.name)
        counts[spec.material.name] = counts.get(spec.material.name, 0) + 1
    assert sorted(counts.values()) == [4, 4, 4]
    for spec in specs:  # the two copies of a clip: two different cloths
        copies = [s for s in choice.specs if clip_name(s) == spec.name]
        assert len({s.material.name for s in copies}) == 2
    both = SequenceSpec(
        in_material(on_body("walk_000", "body01"), "denim"),
        "walk",
        body_name="body01",
        material=FABRICS["denim"],
    )
    assert clip_name(both) == "walk_000"
    one = choose_materials(specs, {"fabrics": ["denim", "jersey"]}, "p")
    assert [s.name for s in one.specs] == [s.name for s in specs] and not one.hold_out  # two: none held out
    assert choose_materials(specs, {}, "p").specs == specs


def test_a_cloth_is_part_of_a_sequences_key_and_none_keeps_the_old_one():
    """The part's key hashes the cloth (a sequence simulated again in another); a spec without one
    keeps the key it had before materials (the keys as commit 98d8d03 computed them)."""
    plain = SequenceSpec("walk_000", "walk", seed=3, seconds=1.0)
    assert plain.key({"template": "x"}) == "c17a066cdd4c6ab8"
    denim = SequenceSpec("walk_000", "walk", seed=3, seconds=1.0, material=FABRICS["denim"])
    jersey = SequenceSpec("walk_000", "walk", seed=3, seconds=1.0, material=FABRICS["jersey"])
    assert (
        len({plain.key({"template": "x"}), denim.key({"template": "x"}), jersey.key({"template": "x"})}) == 3
    )


def test_validation_and_test_hold_out_whole_cloths():
    """Drawn whole: a held-out cloth has no sequence in training, where without the hold-out every
    cloth trains; named: those cloths only test."""
    from hrr_garment.sim.build import BuildSettings
    from hrr_garment.sim.build_split import split_sources

    specs = [SequenceSpec(f"walk_{i:03d}", "walk", seed=i, seconds=1.0) for i in range(60)]
    choice = choose_materials(specs, {"fabrics": ["denim", "jersey", "default", "fleece"]}, "p")
    names, cloth = [s.name for s in choice.specs], {s.name: s.material.name for s in choice.specs}
    trained = {}
    for hold in (False, True):
        options = BuildSettings(splits={"val": 0.25, "test": 0.25}, hold_out_materials=hold)
        split = split_sources(names, choice.specs, options)
        trained[hold] = {cloth[n] for n in split["train"]}
        if hold:
            out = set(cloth.values()) - trained[hold]
            assert out and all(n in split["val"] + split["test"] for n in names if cloth[n] in out)
    assert trained[False] == set(cloth.values()) and trained[True] < trained[False]
    # named: those cloths test, every other trains or validates by its style alone
    named = choose_materials(specs, {"fabrics": "all", "count": 4, "hold_out": ["polyester", "cloth02"]}, "p")
    assert named.hold_out == ("polyester", "cloth02") and named.info["held_out"] == ["polyester", "cloth02"]
    options = BuildSettings(splits={"val": 0.2, "test": 0.2}, hold_out_materials=named.hold_out)
    split = split_sources([s.name for s in named.specs], named.specs, options)
    cloth = {s.name: s.material.name for s in named.specs}
    assert {cloth[n] for n in split["train"] + split["val"]}.isdisjoint({"polyester", "cloth02"})
    assert {n for n in cloth if cloth[n] in ("polyester", "cloth02")} <= set(split["test"])


@pytest.mark.sim  # simulates a tiny dataset: 30-40 s
def test_hrr_simulate_gives_each_sequence_its_cloth_and_the_dataset_records_it(tmp_path, capsys):
    """A preset of two fabrics and a drawn cloth, one a clip: each sequence simulated in its own
    (its part's stats and the dataset's ``material_of``), the choice recorded in the file's info; a
    dataset without materials reads the default cloth for every sequence."""
    pytest.importorskip("newton", reason="the sim extra is not installed")
    from hrr_garment.cli.simulate import main as simulate_main
    from hrr_garment.data.dataset import GarmentDataset

    preset = tmp_path / "p.yaml"
    preset.write_text(
        f"extends: {CONFIG_DIR / 'presets' / 'tiny.yaml'}\nname: tiny-cloths\n"
        "sequences: {walk: 3}\nsplits: {val: 0.0, test: 0.0}\n"
        "materials: {fabrics: [denim, polyester], count: 1, hold_out: false}\n"
    )
    out = tmp_path / "cloths.h5"
    argv = ["--garment", "skirt", "--preset", str(preset), "--seconds", "0.5", "--jobs", "1"]
    # --material: the preset's clips and solver in that one cloth (a specialist's data)
    one = tmp_path / "denim.h5"
    assert simulate_main([*argv, "--material", "denim", "--no-preview", "--quiet", "-o", str(one)]) == 0
    assert "in one cloth: --material takes the place of its materials section" in capsys.readouterr().out
    alone = GarmentDataset(one)
    assert len(alone.names) == 3 and {alone.material_of(n) for n in alone.names} == {FABRICS["denim"]}
    assert "materials" not in alone.info and "materials" not in alone.info["plan"]
    assert alone.info["in_one_cloth"] == "denim"
    # not the preset's own dataset: hrr-train --garment must not take it as out of date and rebuild it
    from hrr_garment.pipeline.simulate import dataset_out_of_date
    from hrr_garment.sim.preset import load_preset

    assert dataset_out_of_date(one, load_preset(str(preset))) is None
    assert simulate_main([*argv, "--no-preview", "--quiet", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert (
        "cloths: 3 (denim, polyester, cloth00)" in printed
        and "cloth denim: 1 sequences (0 rejected)" in printed
    )
    ds = GarmentDataset(out)
    assert {k: v["sequences"] for k, v in ds.info["summary"]["by_material"].items()} == {
        "cloth00": 1,
        "denim": 1,
        "polyester": 1,
    }
    cloths = {ds.material_of(n).name for n in ds.names}
    assert cloths == {"denim", "polyester", "cloth00"} and ds.info["materials"]["count"] == 1
    for name in ds.names:
        cloth = ds.material_of(name)
        assert ds.sequence(name).info["material"]["name"] == cloth.name
        assert cloth.name == "cloth00" or cloth == FABRICS[cloth.name]
    # a dataset of before materials: every sequence in the default cloth
    from hrr_garment.data.dataset import SequenceRecord, write_dataset
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.motion.synth import synthesize

    skirt, motion = make_garment("skirt", 200), synthesize("idle", 0.3, seed=0)
    frames = np.repeat(skirt.vertices[None], motion.num_frames, 0).astype(np.float32)
    old = write_dataset(tmp_path / "old.h5", skirt, [SequenceRecord("a", frames, motion)], {"train": ["a"]})
    assert GarmentDataset(old).material_of("a") == FABRICS["default"]


def test_hrr_make_refuses_a_library_in_many_cloths():
    """hrr-make's budget plans one cloth's simulation: a library preset with a materials section is
    refused, naming it."""
    from dataclasses import replace

    from hrr_garment.pipeline.make_library import motion_library
    from hrr_garment.sim.preset import load_preset

    preset = replace(load_preset("tiny"), materials={"fabrics": ["denim", "jersey"]})
    with pytest.raises(InputError, match="simulated in one cloth") as err:
        motion_library(preset, [])
    assert "tiny" in str(err.value)
