"""Dataset building through the CLI: resume after a kill, the file format, import round trip,
bad inputs (no partial dataset left behind)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hrr_garment.cli.import_sim import main as import_main
from hrr_garment.cli.simulate import main as simulate_main
from hrr_garment.data.dataset import (
    SPLITS,
    DatasetError,
    GarmentDataset,
    SequenceRecord,
    write_dataset,
)
from hrr_garment.data.importer import export_obj_frames
from hrr_garment.data.splits import split_names
from hrr_garment.garment.obj import write_obj
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.io import save_motion
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.plan import plan_sequences
from hrr_garment.sim.preset import load_preset

SIM_ARGS = [
    "--garment",
    "skirt",
    "--preset",
    "tiny",
    "--motions",
    "walk",
    "spin",
    "walk",
    "--seconds",
    "1.0",
    "--jobs",
    "1",
    "--no-preview",
    "--quiet",
]


def test_presets_plan_named_seeded_sequences():
    for name in ("tiny", "quick", "full"):
        preset = load_preset(name)
        specs = plan_sequences(preset)
        assert len({s.name for s in specs}) == len(specs)
        assert plan_sequences(preset) == specs  # same plan on every run
    full = plan_sequences(load_preset("full"))
    assert len(full) >= 50 and sum(s.seconds for s in full) * 30 >= 6000
    quick = load_preset("quick")
    for name, vertices in (("real-quick", 1000), ("real-full", 4000)):  # clips held out by style
        real = load_preset(name)
        assert real.vertices == vertices and real.split_by == "style" and real.mirror
        assert "mocap:bandai/clips.tar.xz" in real.motions
    assert 8000 <= sum(s.seconds for s in plan_sequences(quick)) * 30 <= 9000  # 72 clips of 4 s


def test_test_split_holds_five_sequences_where_the_data_allows():
    from hrr_garment.data.splits import split_groups, test_size

    assert [test_size(n, 0.1) for n in (2, 5, 13, 18, 100)] == [0, 1, 4, 5, 10]
    quick = split_names([f"s{i}" for i in range(18)], 0.1, 0.1, seed=0)
    assert len(quick["test"]) == 5 and len(quick["val"]) == 2 and len(quick["train"]) == 11
    # by group: whole groups until five sequences are held out
    groups = {f"{g}_{i}": g for g in "abcdefgh" for i in range(3)}
    split = split_groups(groups, 0.1, 0.1, seed=0)
    assert 5 <= len(split["test"]) <= 8 and len(split["test"]) % 3 == 0
    assert {groups[n] for n in split["test"]}.isdisjoint(groups[n] for n in split["train"])


def test_split_is_by_sequence_seeded_and_complete():
    names = [f"s{i}" for i in range(20)]
    a, b = split_names(names, 0.1, 0.1, seed=0), split_names(names[::-1], 0.1, 0.1, seed=0)
    assert a == b
    assert (
        sorted(sum(a.values(), [])) == sorted(names) and len(a["val"]) == 2 and len(a["test"]) == 5
    )  # MIN_TEST
    assert split_names(names, 0.1, 0.1, seed=1) != a


@pytest.mark.parametrize("seed", range(6))
def test_split_by_kind_holds_out_only_kinds_that_also_train(seed):
    """The quick preset's procedural clips: every held-out clip's kind keeps a training clip, and
    the split still has its sizes (a tenth each of 72 clips); single-clip kinds all train."""
    from hrr_garment.sim.plan import build_options, plan_sequences
    from hrr_garment.sim.preset import load_preset

    preset = load_preset("quick")
    specs = plan_sequences(preset)
    kinds = build_options(preset, specs)["kinds"]
    split = split_names(list(kinds), 0.1, 0.1, seed, kinds)
    assert sorted(sum(split.values(), [])) == sorted(kinds) and (len(split["val"]), len(split["test"])) == (
        7,
        7,
    )
    trained = {kinds[n] for n in split["train"]}
    assert {kinds[n] for n in split["test"] + split["val"]} <= trained
    assert {k for k, n in preset.sequences.items() if n == 1} <= trained
    # where too few kinds repeat, the rest are held out as without kinds (sizes first)
    few = {"a_0": "a", "a_1": "a", "b_0": "b", "c_0": "c", "d_0": "d", "e_0": "e", "f_0": "f"}
    assert len(split_names(list(few), 0.1, 0.3, seed, few)["test"]) == 2


def test_dataset_file_round_trip(tmp_path):
    garment = make_garment("skirt", 200)
    clip = synthesize("walk", 1.0, seed=0)
    noise = np.random.default_rng(0).normal(scale=0.2, size=(clip.num_frames, garment.num_vertices, 3))
    verts = (clip.root_translation[:, None] + noise).astype(np.float32)  # around the pelvis, as a garment is
    path = write_dataset(
        tmp_path / "d.h5",
        garment,
        [SequenceRecord("walk_000", verts, clip, {"kind": "walk"})],
        {"train": ["walk_000"]},
    )
    ds = GarmentDataset(path)
    rec = ds.sequence("walk_000")
    assert np.array_equal(rec.garment, verts)
    assert np.allclose(rec.motion.joint_positions, clip.joint_positions, atol=1e-5)
    assert np.array_equal(ds.template.attached, garment.attached) and np.array_equal(
        ds.template.faces, garment.faces
    )
    assert ds.splits["train"] == ["walk_000"] and ds.splits["val"] == []
    # its content key: the same frames written again keep it, one vertex moved at the end changes it
    again = write_dataset(
        tmp_path / "again.h5", garment, [SequenceRecord("walk_000", verts, clip)], ds.splits
    )
    moved = verts.copy()
    moved[-1, 7, 1] += 1e-3
    other = write_dataset(
        tmp_path / "moved.h5", garment, [SequenceRecord("walk_000", moved, clip)], ds.splits
    )
    assert GarmentDataset(again).content_key() == ds.content_key() != GarmentDataset(other).content_key()


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A dataset built by a run that was killed after its first sequence, then resumed."""
    pytest.importorskip("newton", reason="the sim extra is not installed")
    out = tmp_path_factory.mktemp("ds") / "skirt.h5"
    parts = out.with_suffix(".parts")
    cmd = [sys.executable, "-m", "hrr_garment.cli.simulate", *SIM_ARGS, "-o", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)

    def finished_parts() -> list[Path]:  # not the hidden temporary file of a part being written
        return [p for p in parts.glob("*.npz") if not p.name.startswith(".")]

    deadline = time.time() + 300
    while time.time() < deadline and not finished_parts():
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)  # the run and its worker processes
    proc.wait()
    done_before = len(finished_parts())
    assert 1 <= done_before < 3 and not out.exists()
    resumed = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    return out, done_before, resumed.stdout


@pytest.mark.sim
def test_killed_build_resumes_and_the_dataset_is_valid(built):
    out, done_before, stdout = built
    assert f"({done_before} reused, {3 - done_before} simulated now, 0 rejected)" in stdout
    ds = GarmentDataset(out)
    assert ds.names == ["spin_000", "walk_000", "walk_001"]
    assert sorted(sum((ds.splits[s] for s in SPLITS), [])) == ds.names
    for name in ds.names:
        rec = ds.sequence(name)
        assert rec.garment.shape == (30, ds.template.num_vertices, 3) and np.isfinite(rec.garment).all()
        assert rec.info["stats"]["strain_p99"] < 1.15
    # Running again reuses everything and rewrites the same data.
    again = subprocess.run(
        [sys.executable, "-m", "hrr_garment.cli.simulate", *SIM_ARGS, "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert "(3 reused, 0 simulated now" in again.stdout
    # where each sequence's motion comes from: here all procedural, so a model of it may ship
    assert set(ds.info["motion_sources"].values()) == {"procedural"} and set(ds.info["sources"]) == {
        "procedural"
    }
    assert "motion sources (sequences): procedural 3; may ship commercially" in again.stdout


@pytest.mark.sim
def test_a_ray_build_equals_the_local_build_bit_for_bit(built, tmp_path):
    """The same sequences as Ray tasks on a local 2-CPU instance: the parts come back to the driver
    and the dataset holds exactly the local build's arrays, motions and splits."""
    pytest.importorskip("ray", reason="the cluster extra is not installed")
    local_path = built[0]
    out = tmp_path / "ray.h5"
    cmd = [
        sys.executable,
        "-m",
        "hrr_garment.cli.simulate",
        *SIM_ARGS,
        "--jobs",
        "2",
        "--executor",
        "ray",
        "-o",
        str(out),
    ]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert "(0 reused, 3 simulated now, 0 rejected)" in run.stdout
    local, remote = GarmentDataset(local_path), GarmentDataset(out)
    assert remote.names == local.names and remote.splits == local.splits
    for name in local.names:
        a, b = local.sequence(name), remote.sequence(name)
        assert np.array_equal(a.garment, b.garment)
        assert np.array_equal(a.motion.local_rotations, b.motion.local_rotations)
        assert np.array_equal(a.motion.root_translation, b.motion.root_translation)
    assert remote.content_key() == local.content_key()  # the same frames from another run


@pytest.mark.sim
def test_a_build_in_a_fabric_records_it_and_differs(built, tmp_path):
    """--material and --air-drag reach the simulator (other frames than the project's cloth) and the
    dataset's record of its settings, which evaluation's truth ensembles re-simulate from."""
    from hrr_garment.sim.simulator import SimSettings

    out = tmp_path / "denim.h5"
    cmd = [sys.executable, "-m", "hrr_garment.cli.simulate", *SIM_ARGS, "--material", "denim"]
    run = subprocess.run(
        [*cmd, "--air-drag", "1.2", "-o", str(out)], capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stderr
    assert "cloth: denim (density 0.324 kg/m^2" in run.stdout and "drag coefficient 1.2" in run.stdout
    denim, plain = GarmentDataset(out), GarmentDataset(built[0])
    sim = SimSettings.from_dict(denim.info["sim"])
    assert sim.material.name == "denim" and sim.air_drag == 1.2 and "material" not in plain.info["sim"]
    name = plain.names[0]
    assert np.abs(denim.sequence(name).garment - plain.sequence(name).garment).max() > 0.01
    assert denim.content_key() != plain.content_key()


@pytest.mark.sim
def test_a_batched_build_equals_the_unbatched_one_and_each_resumes_the_other(built, tmp_path):
    """--batch 3: the three sequences simulated together in one worker (one model, three worlds)
    give the unbatched build's frames (bit-identical on the CPU) in parts of the same keys, so an
    unbatched run resumes a batched build."""
    out = tmp_path / "batched.h5"
    cmd = [sys.executable, "-m", "hrr_garment.cli.simulate", *SIM_ARGS, "--batch", "3", "-o", str(out)]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert "(0 reused, 3 simulated now, 0 rejected)" in run.stdout
    single, batched = GarmentDataset(built[0]), GarmentDataset(out)
    assert batched.names == single.names and batched.splits == single.splits
    for name in single.names:
        assert np.abs(batched.sequence(name).garment - single.sequence(name).garment).max() <= 1e-4
    out.with_suffix(".parts").joinpath("walk_001.npz").unlink()
    out.unlink()
    unbatched = [a for a in cmd if a not in ("--batch", "3")]
    again = subprocess.run(unbatched, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert "(2 reused, 1 simulated now, 0 rejected)" in again.stdout


@pytest.mark.sim
def test_import_round_trip_of_a_simulated_sequence(built, tmp_path):
    out, _, _ = built
    ds = GarmentDataset(out)
    rec = ds.sequence("walk_000")
    template = write_obj(tmp_path / "skirt.obj", ds.template.vertices, ds.template.faces)
    attached = tmp_path / "attached.txt"
    np.savetxt(attached, ds.template.attached, fmt="%d")
    motion = tmp_path / "walk.npz"
    save_motion(rec.motion, motion)
    export_obj_frames(tmp_path / "frames", rec.garment, ds.template.faces)
    target = tmp_path / "imported.h5"
    code = import_main(
        [
            "--garment",
            "skirt",
            "--template",
            str(template),
            "--attached-file",
            str(attached),
            "--motion",
            str(motion),
            "--frames",
            str(tmp_path / "frames"),
            "--name",
            "walk_000",
            "-o",
            str(target),
        ]
    )
    assert code == 0
    back = GarmentDataset(target).sequence("walk_000")
    assert np.abs(back.garment - rec.garment).max() <= 1e-6  # OBJ keeps micrometres
    assert np.allclose(back.motion.local_rotations, rec.motion.local_rotations, atol=1e-6)
    assert np.allclose(back.motion.root_translation, rec.motion.root_translation, atol=1e-9)


def _expect_failure(capsys, main, args, out, *phrases):
    assert main(args) == 2
    err = capsys.readouterr().err
    for phrase in phrases:
        assert phrase in err, err
    assert not out.exists()
    assert not list(out.parent.glob(f".{out.name}*"))  # no temporary file left


def test_bad_inputs_exit_nonzero_and_write_nothing(tmp_path, capsys):
    out = tmp_path / "never.h5"
    _expect_failure(
        capsys, simulate_main, ["--garment", "kimono", "-o", str(out)], out, "kimono", "unknown garment"
    )
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0]], float)
    two = tmp_path / "two.obj"
    write_obj(two, v, np.array([[0, 1, 2], [3, 4, 5]]), {"band": np.array([0, 1, 2])})
    _expect_failure(
        capsys,
        simulate_main,
        ["--template", str(two), "--attached", "band", "-o", str(out)],
        out,
        "two.obj",
        "2 connected components",
    )
    one = tmp_path / "one.obj"
    write_obj(one, v[:3], np.array([[0, 1, 2]]))
    _expect_failure(
        capsys,
        simulate_main,
        ["--template", str(one), "-o", str(out)],
        out,
        "one.obj",
        "no attached vertices",
    )
    short = tmp_path / "short.npz"
    save_motion(synthesize("walk", 1.0, seed=0).slice(0, 5), short)
    _expect_failure(
        capsys,
        simulate_main,
        ["--garment", "skirt", "--motions", str(short), "-o", str(out)],
        out,
        "short.npz",
        "too short",
    )
    _expect_failure(
        capsys,
        simulate_main,
        ["--garment", "skirt", "--preset", "huge", "-o", str(out)],
        out,
        "unknown preset",
    )
    _expect_failure(
        capsys, simulate_main, ["--garment", "skirt", "--material", "velvet", "-o", str(out)], out, "velvet"
    )
    _expect_failure(
        capsys,
        simulate_main,
        ["--garment", "skirt", "--air-drag", "-1", "-o", str(out)],
        out,
        "air_drag must be a number from 0",
    )


def test_train_without_a_dataset_says_how_to_make_one(tmp_path, capsys, monkeypatch):
    from hrr_garment.cli.train import main as train_main

    monkeypatch.setenv("HRR_HOME", str(tmp_path))
    assert train_main(["--garment", "dress", "--stage", "autoencoder"]) == 2
    err = capsys.readouterr().err
    assert "dress-quick.h5" in err and "hrr-simulate --garment dress --preset quick" in err


def test_a_dataset_being_built_is_locked_against_a_second_build(tmp_path):
    from hrr_garment.errors import InputError
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.io_utils import exclusive_lock
    from hrr_garment.sim.build import BuildSettings, build_dataset
    from hrr_garment.sim.simulator import SimSettings

    out = tmp_path / "d.h5"
    with exclusive_lock(out.with_suffix(".lock"), out, "busy"):  # as the first build holds it
        with pytest.raises(InputError, match=r"another hrr-simulate is building this dataset.*process \d+"):
            build_dataset(
                make_garment("skirt", 200), [], SimSettings(), out=out, options=BuildSettings(progress=False)
            )
    # released with its holder: the next build gets past the lock (and finds nothing to simulate)
    with pytest.raises(Exception, match="every sequence failed; nothing to write"):
        build_dataset(
            make_garment("skirt", 200), [], SimSettings(), out=out, options=BuildSettings(progress=False)
        )
    assert not out.exists()


def _damaged(path, damage):
    import h5py

    skirt = make_garment("skirt", 200)
    motion = synthesize("idle", 0.3, seed=0)
    frames = np.repeat(skirt.vertices[None], motion.num_frames, 0).astype(np.float32)
    write_dataset(
        path,
        skirt,
        [SequenceRecord("a", frames, motion)],
        {"train": ["a"], "val": [], "test": []},
        compression=None,
    )
    with h5py.File(path, "r+") as f:
        damage(f)
    return path


def _set(key, value):
    def damage(f):
        f[key][...] = value

    return damage


def _attr(key, value):
    def damage(f):
        (f[key] if key else f).attrs["info"] = value

    return damage


@pytest.mark.parametrize(
    "damage, phrase",
    [
        (lambda f: f.__delitem__("sequences/a/garment"), "sequence 'a' lacks 'garment'"),
        (_set("sequences/a/garment", np.nan), "non-finite garment vertices on 9 frame(s), first at frame 0"),
        (_set("sequences/a/root_translation", np.inf), "sequence 'a': non-finite values in 9 frame(s)"),
        (_attr("sequences/a", "{not json"), "attribute 'info' is not valid JSON"),
        (_attr("", "[1, 2]"), "attribute 'info' should hold a dict"),
        # found by tools/fuzz.py: a damaged template, an array of the wrong shape, a missing motion array
        (_set("template/vertices", np.nan), "its template garment: vertex positions contain NaN"),
        (_set("template/faces", 10**6), "its template garment: face indices must lie in"),
        (lambda f: f.__delitem__("sequences/a/root_translation"), "sequence 'a' lacks 'root_translation'"),
        (
            lambda f: (
                f.__delitem__("sequences/a/garment"),
                f.create_dataset("sequences/a/garment", data=np.zeros((9, 201, 3), np.float32)),
            ),
            "sequence 'a': arrays of mismatched shapes",
        ),
    ],
)
def test_damaged_datasets_are_refused_naming_the_file_and_sequence(tmp_path, damage, phrase):
    path = _damaged(tmp_path / "d.h5", damage)
    with pytest.raises(DatasetError, match=phrase.replace("(", r"\(").replace(")", r"\)")) as info:
        GarmentDataset(path).sequence("a")  # the header's own checks come first where they can
    assert str(path) in str(info.value)


def test_random_bytes_inside_a_chunk_are_a_clear_error(tmp_path):
    path = tmp_path / "d.h5"
    skirt = make_garment("skirt", 200)
    motion = synthesize("idle", 1.0, seed=0)
    frames = (
        np.random.default_rng(0).normal(size=(motion.num_frames, skirt.num_vertices, 3)).astype(np.float32)
    )
    write_dataset(path, skirt, [SequenceRecord("a", frames, motion)], {"train": ["a"], "val": [], "test": []})
    import h5py

    with h5py.File(path, "r") as f:  # where the compressed garment array's first chunk lies in the file
        offset = f["sequences/a/garment"].id.get_chunk_info(0).byte_offset
    data = bytearray(path.read_bytes())
    data[offset + 16 : offset + 4096] = (
        np.random.default_rng(1).integers(0, 256, 4080, dtype=np.uint8).tobytes()
    )
    path.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match="sequence 'a' cannot be read"):
        GarmentDataset(path).sequence("a")


def test_a_damaged_local_heap_is_a_clear_error(tmp_path):
    """HDF5 reports damage to a group's name heap as a RuntimeError ("bad local heap signature"),
    not an OSError (fuzz #782 of 2026-12-04: a traceback from hrr-eval)."""
    path = tmp_path / "d.h5"
    skirt = make_garment("skirt", 200)
    motion = synthesize("idle", 1.0, seed=0)
    frames = np.zeros((motion.num_frames, skirt.num_vertices, 3), np.float32)
    write_dataset(path, skirt, [SequenceRecord("a", frames, motion)], {"train": ["a"], "val": [], "test": []})
    data = path.read_bytes()
    assert b"HEAP" in data
    path.write_bytes(data.replace(b"HEAP", b"HEAQ"))
    with pytest.raises(DatasetError, match="not a readable HDF5 file") as info:
        GarmentDataset(path)
    assert str(path) in str(info.value)


def test_a_garment_far_from_its_body_is_refused(tmp_path):
    """A garment in another unit (scaled x1e6, fuzz #917) trained an autoencoder the bundle check
    then refused, and left the model folder: the dataset refuses it when read."""
    garment = make_garment("skirt", 200)
    clip = synthesize("walk", 1.0, seed=0)
    verts = (
        np.repeat(garment.vertices[None], clip.num_frames, 0) + clip.root_translation[:, None] - [0, 0.95, 0]
    )
    path = write_dataset(
        tmp_path / "d.h5",
        garment,
        [SequenceRecord("walk_000", (verts * 1e6).astype(np.float32), clip, {"kind": "walk"})],
        {"train": ["walk_000"]},
    )
    with pytest.raises(DatasetError, match="from the pelvis at frame 0, beyond 3 m"):
        GarmentDataset(path).sequence("walk_000")
