"""Presets that name motion files: globs, folders, archives, clip groups held out whole, mirroring."""

import tarfile
from pathlib import Path

import numpy as np
import pytest

from hrr_garment.data.splits import split_groups
from hrr_garment.errors import InputError
from hrr_garment.motion.io import save_motion
from hrr_garment.motion.skeleton import MIRROR_JOINTS
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.motion_sources import spec_sources
from hrr_garment.sim.plan import build_options, plan_sequences
from hrr_garment.sim.preset import load_preset, plan_record
from hrr_garment.sim.sources import clip_group, resolve_motion_entries


@pytest.fixture
def library(tmp_path, monkeypatch):
    """A folder of Bandai-style clip names, the same clips in a .tar.xz, and a preset beside them."""
    monkeypatch.setenv("HRR_HOME", str(tmp_path / "work"))
    clips = tmp_path / "lib" / "clips"
    clips.mkdir(parents=True)
    for i, (content, style) in enumerate(
        [("walk", "proud"), ("walk", "sad"), ("run", "proud"), ("bow", "sad"), ("bow", "old"), ("run", "old")]
    ):
        save_motion(synthesize("walk", 1.0, seed=i), clips / f"dataset-1_{content}_{style}_{i:03d}.npz")
    with tarfile.open(tmp_path / "lib" / "clips.tar.xz", "w:xz") as tar:
        tar.add(clips, arcname="pack")
    return tmp_path / "lib"


def test_entries_resolve_globs_folders_and_archives(library, tmp_path):
    by_glob = resolve_motion_entries(["clips/*walk*.npz"], base=library)
    assert [p.name for p in by_glob] == ["dataset-1_walk_proud_000.npz", "dataset-1_walk_sad_001.npz"]
    by_folder = resolve_motion_entries([str(library / "clips")])
    assert len(by_folder) == 6
    by_archive = resolve_motion_entries(["clips.tar.xz"], base=library)
    assert [p.name for p in by_archive] == [p.name for p in by_folder]
    unpacked = by_archive[0].parents[1]
    assert unpacked.is_relative_to(tmp_path / "work" / "mocap")  # into the workspace, not beside the archive
    again = resolve_motion_entries(["clips.tar.xz"], base=library)  # unpacked once, read from there after
    assert again == by_archive
    with pytest.raises(InputError, match="names no file"):
        resolve_motion_entries(["clips/*.bvh"], base=library)


def test_groups_are_held_out_whole(library, tmp_path):
    preset_file = library / "lib.yaml"
    preset_file.write_text(
        "name: lib\nvertices: 300\nseconds: 1.0\nsequences: {}\nmotions: [clips.tar.xz]\n"
        "split_by: style\nsplits: {val: 0.2, test: 0.3}\nspeed_warps: [1.25]\n"
    )
    preset = load_preset(str(preset_file))
    specs = plan_sequences(preset)
    assert len(specs) == 12 and sum(s.speed == 1.25 for s in specs) == 6
    fast = next(s for s in specs if s.speed == 1.25)
    assert fast.stop - fast.start == 24  # 30 frames played 1.25 times faster
    options = build_options(preset, specs)
    groups = options["groups"]
    assert set(groups.values()) == {"style=proud", "style=sad", "style=old"}
    assert options["info"]["split_by"] == "style"
    split = split_groups(groups, 0.2, 0.3, seed=0)
    assert sorted(sum(split.values(), [])) == sorted(groups)
    held = {s: {groups[n] for n in names} for s, names in split.items()}
    assert all(held[a].isdisjoint(held[b]) for a in held for b in held if a != b)  # no style in two splits
    assert held["test"] and held["val"] and held["train"]


def test_clip_group_falls_back_to_the_name():
    assert clip_group("dataset-2_wave-left-hand_elderly_003", "style") == "style=elderly"
    assert clip_group("dataset-2_wave-left-hand_elderly_003", "content") == "content=wave-left-hand"
    assert clip_group("02_01", "style") == "02_01"


def test_mirrored_motion_mirrors_every_joint():
    motion = synthesize("dance", 1.5, seed=2)
    mirrored = motion.mirrored()
    flip = np.array([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(
        mirrored.joint_positions, motion.joint_positions[:, list(MIRROR_JOINTS)] * flip, atol=1e-5
    )
    np.testing.assert_allclose(mirrored.mirrored().local_rotations, motion.local_rotations, atol=1e-6)


def test_mirrored_sequences_join_their_source_split():
    from hrr_garment.data.dataset import SequenceRecord
    from hrr_garment.garment.mesh import mirror_map
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.sim.reflection import add_reflected_mirrors

    garment = make_garment("dress", 300)
    perm = mirror_map(garment.vertices)
    assert perm is not None
    motion = synthesize("walk", 1.0, seed=0)
    frames = garment.vertices[None] + np.random.default_rng(0).normal(
        0, 0.01, (motion.num_frames, garment.num_vertices, 3)
    )
    records = [
        SequenceRecord("a", frames.astype(np.float32), motion),
        SequenceRecord("b", frames.astype(np.float32), motion),
    ]
    out, split = add_reflected_mirrors(
        records, {"train": ["a"], "test": ["b"], "val": []}, garment, progress=False
    )
    assert split == {"train": ["a", "a_mirror"], "test": ["b", "b_mirror"], "val": []}
    mirrored = next(r for r in out if r.name == "a_mirror")
    # Reflecting twice gives the frames back; each vertex lands where its mirror partner was.
    np.testing.assert_allclose(mirrored.garment[:, perm] * [-1, 1, 1], frames, atol=1e-6)
    assert mirrored.info["mirror_of"] == "a"
    # a sequence on a body that is not its own mirror image is not mirrored (the mirror would stand
    # on another body)
    from dataclasses import replace

    from hrr_garment.body.body_file import BodyRecord
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.garment.dressing import DressedBody

    lopsided = DEFAULT_BODY.capsules[:-1] + (replace(DEFAULT_BODY.capsules[-1], radius=0.2),)
    body = replace(DEFAULT_BODY, capsules=lopsided)
    bodies = {"odd": DressedBody("odd", BodyRecord(body.skeleton, body, body.pelvis_height, 1.7), garment)}
    records[1] = SequenceRecord("b", frames.astype(np.float32), motion, body_name="odd")
    out, split = add_reflected_mirrors(
        records, {"train": ["a"], "test": ["b"], "val": []}, garment, progress=False, bodies=bodies
    )
    assert split == {"train": ["a", "a_mirror"], "test": ["b"], "val": []} and len(out) == 3


def test_mirror_modes_of_a_preset(tmp_path):
    from hrr_garment.sim.plan import SequenceSpec
    from hrr_garment.sim.preset import mirror_mode

    assert [mirror_mode(v) for v in (True, False, None, "simulate", "reflect", "sideways")] == [
        "simulate",
        "",
        "",
        "simulate",
        "reflect",
        None,
    ]
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nvertices: 300\nseconds: 1.0\nsequences: {walk: 1}\nmirror: sideways\n")
    with pytest.raises(InputError, match="mirror: 'sideways'"):
        load_preset(str(bad))
    good = tmp_path / "good.yaml"
    good.write_text("name: good\nvertices: 300\nseconds: 1.0\nsequences: {walk: 1}\nmirror: true\n")
    preset = load_preset(str(good))
    options = build_options(preset, plan_sequences(preset))
    assert options["mirror"] == "simulate" and options["info"]["augmentation"]["mirror"] == "simulate"
    # a mirrored spec plays the reflected motion under a key of its own; its source's key is the
    # key it had before the field existed (finished parts stay reusable)
    spec = SequenceSpec("walk_000", "walk", seed=3, seconds=1.0)
    mirrored = SequenceSpec("walk_000_mirror", "walk", seed=3, seconds=1.0, mirrored=True)
    np.testing.assert_allclose(
        mirrored.motion().joint_positions, spec.motion().mirrored().joint_positions, atol=1e-9
    )
    assert spec.key({}) == "a42fdcd307411965" and mirrored.key({}) != spec.key({})


def test_simulated_mirrors_join_their_source_split():
    """With ``mirror: simulate`` the split is drawn over the sources (the split they get alone) and
    each mirror goes where its source goes, also when the source itself failed."""
    from dataclasses import replace

    from hrr_garment.sim.build import BuildSettings
    from hrr_garment.sim.build_split import split_finished
    from hrr_garment.sim.plan import SequenceSpec

    sources = [SequenceSpec(f"walk_{i:03d}", "walk", seed=i, seconds=1.0) for i in range(10)]
    options = BuildSettings(splits={"val": 0.2, "test": 0.2}, seed=1, kinds={s.name: "walk" for s in sources})
    alone = split_finished([s.name for s in sources], sources, options)
    done = [s.name for s in sources] + [f"{s.name}_mirror" for s in sources if s.name != "walk_004"]
    done.remove("walk_007")  # its mirror simulated, the source did not
    split = split_finished(done, sources, replace(options, mirror="simulate"))
    for part, names in alone.items():
        expected = {n for n in names if n != "walk_007"} | {f"{n}_mirror" for n in names if n != "walk_004"}
        assert set(split[part]) == expected


@pytest.mark.slow
@pytest.mark.parametrize(
    "sequences,motions,missing",
    [
        ({"walk": 3, "spin": 1, "run": 1}, None, []),
        ({"walk": 4, "spin": 2, "run": 1}, None, ["spin_001", "walk_003"]),
        ({"walk": 4, "spin": 2, "run": 1}, ["walk", "spin"], []),
    ],
)
def test_hrr_train_simulates_what_a_grown_preset_adds(tmp_path, monkeypatch, sequences, motions, missing):
    """A workspace's dataset made with an earlier, smaller version of a preset: hrr-train simulates
    the sequences it lacks (build_dataset reuses the finished ones) instead of training on it; a
    dataset of the user's own clips (hrr-simulate --motions) is left as it is."""
    import json

    import h5py
    import yaml

    import hrr_garment.cli.train as train_cli
    import hrr_garment.pipeline.simulate as pipeline
    from hrr_garment.garment.templates import make_garment
    from tests.conftest import synthetic_dataset

    monkeypatch.setenv("HRR_HOME", str(tmp_path))
    (tmp_path / "datasets").mkdir()
    dataset = synthetic_dataset(
        tmp_path / "datasets" / "skirt-grown.h5", make_garment("skirt", 300)
    )  # run, spin, walk x 3
    with h5py.File(dataset, "a") as f:  # as hrr-simulate records what it simulated
        f.attrs["info"] = json.dumps({"preset": "grown", "motions": motions})
    preset = tmp_path / "grown.yaml"
    preset.write_text(
        yaml.safe_dump({"name": "grown", "vertices": 300, "seconds": 2.0, "sequences": sequences})
    )
    calls = []
    monkeypatch.setattr(
        pipeline,
        "simulate_preset",
        lambda garment, p, out, progress=True: calls.append((garment, p.name, out)),
    )
    assert sorted(pipeline.missing_sequences(dataset, load_preset(str(preset)))) == missing
    assert (
        train_cli.main(["--garment", "skirt", "--preset", str(preset), "--stage", "simulate", "--quiet"]) == 0
    )
    assert calls == ([("skirt", "grown", dataset)] if missing else [])
    assert pipeline.missing_sequences(tmp_path / "nothing.h5", load_preset(str(preset))) == []


def test_more_fields_held_out_whole_beside_the_split(library, tmp_path):
    """``also_hold_out``: whole contents held out beside whole styles; a content tests in none of
    its takes' styles, and the hold-out each test clip stands for is the one it belongs to."""
    from hrr_garment.eval.holdouts import holdout_of
    from hrr_garment.sim.build import BuildSettings
    from hrr_garment.sim.build_split import split_finished

    preset_file = library / "lib.yaml"
    preset_file.write_text(
        "name: lib\nvertices: 300\nseconds: 1.0\nsequences: {walk: 1}\nmotions: [clips.tar.xz]\n"
        "split_by: style\nsplits: {val: 0.2, test: 0.2}\nalso_hold_out: {content: {test: 0.3}}\n"
    )
    preset = load_preset(str(preset_file))
    specs = plan_sequences(preset)
    options = build_options(preset, specs)
    content = options["also_hold_out"]["content"]
    assert set(content["groups"].values()) == {"content=walk", "content=run", "content=bow"}
    assert (
        "walk_000" not in content["groups"]
    )  # a procedural clip has no content field: it is not held out by it
    names = [s.name for s in specs]
    split = split_finished(names, specs, BuildSettings(**options))
    assert sorted(sum(split.values(), [])) == sorted(names)
    trained = {content["groups"][n] for n in split["train"] if n in content["groups"]}
    tested = {content["groups"][n] for n in split["test"] if n in content["groups"]}
    unseen = tested - trained
    assert unseen  # at least one content tests in every take
    style_only = split_finished(names, specs, BuildSettings(**{**options, "also_hold_out": None}))
    assert set(style_only["test"]) <= set(split["test"])  # the styles held out as before, and more
    kinds = holdout_of(options["info"], split, split["test"])
    assert {n for n, k in kinds.items() if k == "content"} == {
        n for n in split["test"] if content["groups"].get(n) in unseen
    }
    assert all(
        kinds[n] == "style"
        for n in split["test"]
        if content["groups"].get(n) not in unseen
        and n in options["groups"]
        and options["groups"][n].startswith("style=")
    )


@pytest.mark.parametrize(
    "text, problem",
    [
        ("{mood: {test: 0.1}}", "not a field"),
        ("{content: {test: 0.7}}", "fractions"),
        ("{content: {train: 0.1}}", "fractions"),
    ],
)
def test_a_bad_also_hold_out_is_refused(library, text, problem):
    preset_file = library / "bad.yaml"
    preset_file.write_text(
        f"name: bad\nvertices: 300\nseconds: 1.0\nsequences: {{}}\nalso_hold_out: {text}\n"
    )
    with pytest.raises(InputError, match=problem):
        load_preset(str(preset_file))


@pytest.mark.parametrize(
    "text, problem",
    [
        ("{stops: 2, stop_hold_s: 0.01}", "stop_hold_s must be at least one frame"),
        ("{stops: 2, stop_motion_s: 0}", "stop_motion_s must be at least one frame"),
        ("{stops: -1}", "not understood"),
        ("{stops: 2, hold: 3}", "not understood"),
    ],
)
def test_bad_stops_are_refused_naming_the_file(library, text, problem):
    preset_file = library / "bad.yaml"
    preset_file.write_text(f"name: bad\nvertices: 300\nseconds: 1.0\nsequences: {{}}\nsplices: {text}\n")
    with pytest.raises(InputError, match=problem) as refused:
        load_preset(str(preset_file))
    assert "bad.yaml" in str(refused.value)


@pytest.mark.parametrize(
    "recorded,expected",
    [
        (True, ["run_000_mirror", "walk_000_mirror"]),
        ("reflect", ["run_000_mirror", "walk_000_mirror"]),
        ("simulate", []),
    ],
)
def test_a_dataset_of_reflections_gets_its_mirrors_simulated(tmp_path, recorded, expected):
    """A workspace dataset whose mirrors are reflections (files written before mirrors were
    simulated record ``true``): hrr-train's simulate stage simulates the mirrors of a preset that now
    simulates them; a dataset whose mirrors were simulated (and its splices) is complete."""
    import json

    import h5py
    import yaml

    import hrr_garment.pipeline.simulate as pipeline
    from hrr_garment.data.dataset import SequenceRecord, write_dataset
    from hrr_garment.garment.templates import make_garment

    garment = make_garment("skirt", 200)
    clip = synthesize("walk", 1.0, seed=0)
    frames = np.repeat(garment.vertices[None], clip.num_frames, axis=0) + clip.root_translation[
        :, None
    ].astype(np.float32)
    names = ["run_000", "walk_000", "run_000_mirror", "walk_000_mirror", "splice_000"]
    dataset = write_dataset(
        tmp_path / "d.h5", garment, [SequenceRecord(n, frames, clip) for n in names], {"train": names}
    )
    with h5py.File(dataset, "a") as f:
        f.attrs["info"] = json.dumps({"preset": "mirrored", "augmentation": {"mirror": recorded}})
    preset = tmp_path / "mirrored.yaml"
    preset.write_text(
        yaml.safe_dump(
            {
                "name": "mirrored",
                "vertices": 200,
                "seconds": 1.0,
                "sequences": {"walk": 1, "run": 1},
                "mirror": True,
            }
        )
    )
    assert sorted(pipeline.missing_sequences(dataset, load_preset(str(preset)))) == expected


def test_a_dataset_made_before_its_preset_changed_is_made_again(tmp_path):
    """A dataset records the preset's settings that decide its sequences (``info.plan``): the same
    preset finds it complete; one whose bodies or splices changed (which the names do not show)
    finds it out of date and says which settings changed; a file written before the record is out of
    date only where names are missing or the preset has bodies or splices."""
    import json

    import h5py
    import yaml

    from hrr_garment.data.dataset import SequenceRecord, write_dataset
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.pipeline.simulate import dataset_out_of_date
    from hrr_garment.sim.preset import plan_record

    garment = make_garment("skirt", 200)
    clip = synthesize("walk", 1.0, seed=0)
    frames = np.repeat(garment.vertices[None], clip.num_frames, axis=0)
    dataset = write_dataset(
        tmp_path / "d.h5", garment, [SequenceRecord("walk_000", frames, clip)], {"train": ["walk_000"]}
    )
    settings = {"name": "p", "vertices": 200, "seconds": 1.0, "sequences": {"walk": 1}}
    preset_file = tmp_path / "p.yaml"

    def out_of_date(recorded: dict | None, now: dict) -> str | None:
        preset_file.write_text(yaml.safe_dump(now))
        with h5py.File(dataset, "a") as f:
            info = {"preset": "p"}
            if recorded is not None:
                preset_file.write_text(yaml.safe_dump(recorded))
                info["plan"] = plan_record(load_preset(str(preset_file)))
                preset_file.write_text(yaml.safe_dump(now))
            f.attrs["info"] = json.dumps(info)
        return dataset_out_of_date(dataset, load_preset(str(preset_file)))

    assert out_of_date(settings, settings) is None
    assert (
        out_of_date(settings, {**settings, "train": {"codespace": {"train": {"epochs": 3}}}}) is None
    )  # training only
    bodies = {**settings, "bodies": {"from": "sample", "per_clip": 2}}
    assert out_of_date(bodies, bodies) is None
    assert (
        out_of_date(bodies, {**settings, "bodies": {"from": "sample", "per_clip": 2, "mannequin": True}})
        == "was made with other bodies settings than the p preset's"
    )
    assert "splices" in out_of_date(settings, {**settings, "splices": {"backward": 3}})
    assert out_of_date(None, settings) is None  # before the record: the names are the preset's
    assert "lacks 1" in out_of_date(None, {**settings, "sequences": {"walk": 2}})
    assert "predates the record" in out_of_date(None, bodies)
    assert dataset_out_of_date(tmp_path / "none.h5", load_preset(str(preset_file))) is None


def test_a_motion_file_may_not_take_an_added_sequences_name(tmp_path):
    save_motion(synthesize("walk", 1.0, seed=0), tmp_path / "backward_000.npz")
    preset_file = tmp_path / "p.yaml"
    preset_file.write_text(
        "name: p\nvertices: 200\nseconds: 1.0\nsequences: {}\nmotions: [backward_000.npz]\n"
    )
    with pytest.raises(InputError, match="backward_000.npz.*rename the file"):
        plan_sequences(load_preset(str(preset_file)))


def test_each_file_keeps_its_source_and_a_commercial_only_preset_leaves_out_the_rest(
    library, tmp_path, monkeypatch, capsys
):
    mocap = tmp_path / "mocap"
    for folder in ("bandai", "cmu"):
        (mocap / folder).mkdir(parents=True)
    save_motion(synthesize("walk", 1.0, seed=0), mocap / "bandai" / "dataset-1_walk_proud_000.npz")
    save_motion(synthesize("run", 1.0, seed=1), mocap / "cmu" / "09_01.npz")
    save_motion(synthesize("spin", 1.0, seed=2), library / "mine.npz")
    monkeypatch.setenv("HRR_MOCAP_DIR", str(mocap))
    text = (
        "name: lic\nvertices: 300\nseconds: 1.0\nsequences: {walk: 1}\nmirror: true\n"
        "motions: ['mocap:bandai/*.npz', 'mocap:cmu/*.npz', mine.npz,\n"
        "          {path: 'clips/*walk_sad*', source: bandai}]\n"
    )
    (library / "lic.yaml").write_text(text)
    preset = load_preset(str(library / "lic.yaml"))
    specs = plan_sequences(preset)
    sources = build_options(preset, specs)["file_sources"]
    assert {Path(p).name: s for p, s in sources.items()} == {
        "dataset-1_walk_proud_000.npz": "bandai",
        "09_01.npz": "cmu",
        "mine.npz": "own",
        "dataset-1_walk_sad_001.npz": "bandai",  # declared
    }
    assert {spec_sources(s, sources) for s in specs} == {"bandai", "cmu", "own", "procedural"}
    (library / "clean.yaml").write_text(text.replace("name: lic", "name: clean\ncommercial_only: true"))
    clean = load_preset(str(library / "clean.yaml"))
    kept = plan_sequences(clean)
    assert sorted(s.name for s in kept) == ["09_01", "mine", "walk_000"]
    build_options(clean, kept)
    assert "left out mocap:bandai/*.npz, clips/*walk_sad*" in capsys.readouterr().out
    assert plan_record(clean)["commercial_only"] is True and "commercial_only" not in plan_record(preset)


def test_a_motion_entry_declaring_an_unknown_source_is_refused(library):
    (library / "bad.yaml").write_text(
        "name: bad\nvertices: 300\nseconds: 1.0\nsequences: {}\nmotions: [{path: clips, source: mixamo}]\n"
    )
    with pytest.raises(InputError, match="declares source 'mixamo'; known: bandai"):
        load_preset(str(library / "bad.yaml"))
