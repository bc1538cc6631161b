"""Which bodies a build simulates on: the preset's bodies section checked, sampled bodies spread over
the statures asked for, every clip on its bodies, presets that extend another."""

import pytest

from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.errors import InputError
from hrr_garment.garment.templates import make_garment
from hrr_garment.sim.body_plan import BodyPlan, plan_bodies
from hrr_garment.sim.plan import SequenceSpec
from hrr_garment.sim.preset import load_preset


@pytest.mark.parametrize(
    "section, phrase",
    [
        ({"from": "nowhere"}, "'from' must be"),
        ({"from": "sample", "colour": 1}, "colour"),
        ({"from": "sample", "count": 4, "per_clip": 5}, "per_clip"),
        ({"from": "sample", "statures_m": [1.9, 1.5]}, "low first"),
    ],
)
def test_a_bad_bodies_section_is_refused_naming_the_preset(section, phrase):
    with pytest.raises(InputError, match=phrase) as err:
        BodyPlan.from_preset(section, "my-preset.yaml")
    assert "my-preset.yaml" in str(err.value)


def test_no_bodies_section_is_the_mannequin():
    assert BodyPlan.from_preset({}, "p") is None


def test_sampled_bodies_span_the_statures_and_share_the_clips():
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    plan = BodyPlan("sample", count=3, per_clip=2, statures_m=(1.5, 1.9))
    specs = [SequenceSpec(f"walk_{i:03d}", "walk", seed=i, seconds=1.0) for i in range(3)]
    planned, bodies = plan_bodies(
        plan, specs, make_garment("skirt", 200), made_for=DEFAULT_BODY, progress=False
    )
    statures = sorted(b.record.stature for b in bodies.values())
    assert statures == pytest.approx([1.5, 1.7, 1.9], abs=0.005)
    assert len(planned) == 6 and len({s.name for s in planned}) == 6
    for spec in specs:  # each clip on two different bodies
        mine = [s.body_name for s in planned if s.name.startswith(spec.name + "__")]
        assert len(set(mine)) == 2
    assert sorted(s.body_name for s in planned) == sorted(list(bodies) * 2)  # every body gets its share
    assert {s.shape["gender"] for s in (b.record for b in bodies.values())} == {0.0, 1.0}


def test_a_preset_extends_another_and_replaces_only_what_it_names():
    base, bodies = load_preset("real-quick"), load_preset("real-quick-bodies")
    assert bodies.name == "real-quick-bodies" and bodies.bodies["from"] == "sample"
    assert (bodies.motions, bodies.sim, bodies.sequences, bodies.mirror) == (
        base.motions,
        base.sim,
        base.sequences,
        base.mirror,
    )
    assert load_preset("real-quick-performers").bodies == {"from": "performer"}


def test_a_users_preset_file_extends_a_built_in_preset_by_its_name(tmp_path):
    """A file outside configs/presets names a built-in as its parent; a sibling file of that name wins."""
    (tmp_path / "mine.yaml").write_text(
        "extends: real-quick\nname: mine\nmirror: false\ntrain: {codespace: {train: {epochs: 3}}}\n"
    )
    mine, base = load_preset(str(tmp_path / "mine.yaml")), load_preset("real-quick")
    assert (mine.name, mine.mirror, mine.motions, mine.sim) == ("mine", False, base.motions, base.sim)
    assert mine.train["codespace"]["train"]["epochs"] == 3
    assert mine.train["codespace"]["train"]["latent_loss"] == base.train["codespace"]["train"]["latent_loss"]
    (tmp_path / "real-quick.yaml").write_text(
        "name: local\nvertices: 300\nseconds: 2.0\nsequences: {walk: 1}\n"
    )
    assert load_preset(str(tmp_path / "mine.yaml")).vertices == 300
    (tmp_path / "orphan.yaml").write_text("extends: no-such-preset\nname: orphan\n")
    with pytest.raises(InputError, match="not a valid preset"):
        load_preset(str(tmp_path / "orphan.yaml"))


def test_every_clip_on_the_mannequin_as_well_holds_out_the_same_bodies():
    """``mannequin: true``: each clip also on the mannequin under its own name (a dataset of the mannequin
    alone holds its part), the mannequin never held out as a body, the sampled bodies held out as
    without it."""
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    from hrr_garment.data.splits import split_groups
    from hrr_garment.sim.build import BuildSettings
    from hrr_garment.sim.build_split import split_sources
    from hrr_garment.sim.plan import clip_name

    assert BodyPlan.from_preset({"from": "sample", "mannequin": True}, "p").mannequin
    with pytest.raises(InputError, match="from: sample"):
        BodyPlan.from_preset({"from": "performer", "mannequin": True}, "p")
    specs = [SequenceSpec(f"walk_{i:03d}", "walk", seed=i, seconds=1.0) for i in range(8)]
    garment = make_garment("skirt", 200)
    held_out_bodies = {}
    for mannequin in (False, True):
        plan = BodyPlan("sample", count=4, per_clip=2, statures_m=(1.5, 1.9), mannequin=mannequin)
        planned, bodies = plan_bodies(plan, specs, garment, made_for=DEFAULT_BODY, progress=False)
        groups = {s.name: clip_name(s) for s in planned}  # a clip's sequences share its group
        options = BuildSettings(splits={"val": 0.25, "test": 0.25}, groups=groups, hold_out_bodies=True)
        split = split_sources([s.name for s in planned], planned, options)
        trained = {s.body_name for s in planned if s.name in split["train"]}
        held_out_bodies[mannequin] = set(bodies) - trained
        assert len(planned) == len(specs) * (3 if mannequin else 2) and len(bodies) == 4
    assert held_out_bodies[True] == held_out_bodies[False] and held_out_bodies[True]
    on_mannequin = sorted(s.name for s in planned if not s.body_name)
    assert on_mannequin == [s.name for s in specs]  # every clip, under its own name
    by_clip = split_groups(groups, 0.25, 0.25, seed=0)  # the mannequin's sequences follow their clips alone
    for k in ("train", "val", "test"):
        assert sorted(set(split[k]) & set(on_mannequin)) == sorted(set(by_clip[k]) & set(on_mannequin))
    assert set(split["train"]) & set(on_mannequin)


def test_a_procedural_clip_on_several_bodies_is_one_split_group():
    """Its copies on bodies (``clip__body``) and on the mannequin split together, so the clips a preset
    holds out do not depend on how many bodies each clip stands on."""
    from dataclasses import replace

    from hrr_garment.sim.plan import sequence_group

    preset = load_preset("real-quick-bodies")
    spec = SequenceSpec("walk_000", "walk", seed=0, seconds=1.0)
    copies = [spec] + [replace(spec, name=f"walk_000__{b}", body_name=b) for b in ("body03", "body07")]
    assert {sequence_group(s, preset) for s in copies} == {"walk_000"}
    assert (
        sequence_group(replace(spec, name="walk_000__x", body_name="body03"), preset) == "walk_000__x"
    )  # not a body's suffix


def test_without_split_by_a_clip_on_several_bodies_splits_as_the_clip_alone():
    """No ``split_by`` (procedural presets): the split is drawn over clips, in distribution over their
    kinds, and every copy of a clip on a body goes where the clip goes."""
    from dataclasses import replace

    from hrr_garment.sim.build import BuildSettings
    from hrr_garment.sim.build_split import split_sources
    from hrr_garment.sim.plan import on_body

    clips = [
        SequenceSpec(f"{k}_{i:03d}", k, seed=i, seconds=1.0)
        for k in ("walk", "run", "spin")
        for i in range(4)
    ]
    kinds = {s.name: s.kind for s in clips}
    alone = split_sources(
        sorted(kinds), clips, BuildSettings(splits={"val": 0.2, "test": 0.2}, seed=2, kinds=kinds)
    )
    copies = [
        replace(s, name=on_body(s.name, b), body_name=b) for s in clips for b in ("body01", "body04")
    ] + clips
    options = BuildSettings(splits={"val": 0.2, "test": 0.2}, seed=2, kinds={s.name: s.kind for s in copies})
    split = split_sources(sorted(s.name for s in copies), copies, options)
    for part, names in alone.items():
        assert split[part] == sorted(
            c for n in names for c in (n, on_body(n, "body01"), on_body(n, "body04"))
        )


@pytest.mark.parametrize("key", ["mannequin", "hold_out"])
def test_a_bodies_flag_is_true_or_false(key):
    with pytest.raises(InputError, match=f"{key} must be true or false"):
        BodyPlan.from_preset({"from": "sample", key: "false"}, "p.yaml")


def test_a_sequence_on_a_body_keeps_the_key_it_had_before_its_body_name_was_renamed():
    """``SequenceSpec.body_name`` was ``body``: it hashes under that name, so a build finds the parts
    it simulated before the rename (the keys as commit 98d8d03 computed them)."""
    on_body = SequenceSpec("walk_000__tall", "walk", seed=3, seconds=1.0, body_name="tall")
    assert on_body.key({"template": "x"}) == "e9a77a6bbc6b149d"
    assert SequenceSpec("walk_000", "walk", seed=3, seconds=1.0).key({"template": "x"}) == "c17a066cdd4c6ab8"
