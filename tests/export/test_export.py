"""Exports (GLB, USD, PC2, OBJ), the keyframe bound, the rasterizer and hrr-preview."""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.data.animation_file import AnimationArrays, read_animation_h5, write_animation_h5
from hrr_garment.export.keyframes import interpolate, select_keyframes
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.synth import synthesize

ROOT = Path(__file__).resolve().parents[2]


def _animation_arrays(frames: int = 40, seed: int = 0) -> dict:
    """A skirt carried along a walk with a swing that is not linear in time (so keyframes matter)."""
    motion = synthesize("walk", frames / 30.0, seed=seed)
    skirt = make_garment("skirt", 300)
    t = np.arange(motion.num_frames)[:, None, None] / 30.0
    pelvis = motion.joint_positions[:, :1] * np.array([1.0, 0.0, 1.0])  # carried along by the body, around it
    sway = 0.03 * np.sin(2 * np.pi * 1.3 * t + skirt.vertices[None, :, 1:2] * 4) * np.array([1.0, 0.2, 0.5])
    vertices = skirt.vertices[None] + pelvis + sway
    a, b = DEFAULT_BODY.pose_motion(motion)
    retrieved = (np.arange(motion.num_frames) // 10 % 2).astype(np.uint8)
    return dict(
        vertices=vertices.astype(np.float32),
        faces=skirt.faces,
        joints=motion.joint_positions,
        retrieved=retrieved,
        entropy=np.zeros(motion.num_frames),
        match=np.full((motion.num_frames, 2), -1),
        attrs={"fps": 30.0, "garment": "skirt", "source_motion": "walk"},
        capsules=np.stack([a, b], 2),
        radii=DEFAULT_BODY.radii,
    )


def _write(path: Path, arrays: dict) -> Path:
    """An out.h5 of ``arrays`` (as :func:`_animation_arrays` gives them, its ``attrs`` included)."""
    arrays = dict(arrays)
    attrs = arrays.pop("attrs")
    return write_animation_h5(path, AnimationArrays(**arrays), attrs)


@pytest.fixture
def out_h5(tmp_path) -> Path:
    return _write(tmp_path / "out.h5", _animation_arrays())


# ---------------------------------------------------------------- keyframes


@pytest.mark.parametrize("tolerance", [0.0, 0.0005, 0.002, 0.01])
def test_keyframes_keep_every_frame_within_the_tolerance(tolerance):
    v = _animation_arrays(60)["vertices"].astype(np.float64)
    keys = select_keyframes(v, tolerance)
    assert keys.frames[0] == 0 and keys.frames[-1] == len(v) - 1 and np.all(np.diff(keys.frames) > 0)
    err = np.linalg.norm(interpolate(v, keys.frames) - v, axis=-1).max()
    assert err <= tolerance + 1e-12 and abs(err - keys.max_error) < 1e-9
    if tolerance == 0:
        assert len(keys.frames) == len(v)
    if tolerance >= 0.01:
        assert len(keys.frames) < len(v) / 2  # the reduction does something


def test_keyframes_of_linear_motion_are_the_two_ends():
    base = np.random.default_rng(0).normal(size=(50, 3))
    v = base[None] + np.linspace(0, 1, 30)[:, None, None] * np.array([0.5, 0.0, 1.0])
    assert select_keyframes(v, 1e-6, max_span=100).frames.tolist() == [0, 29]
    assert np.all(np.diff(select_keyframes(v, 1e-6, max_span=8).frames) <= 8)


# ---------------------------------------------------------------- GLB


def _node_script(package: str, script: str) -> tuple[list[str], dict]:
    """The command that runs ``tools/<script>`` in node with the npm ``package`` found (``make
    install`` puts it in .venv/node), and its environment; a skip without node, a failure when node
    is there but the package is not."""
    node = shutil.which("node")
    modules = Path(os.environ.get("HRR_NODE_MODULES", ROOT / ".venv" / "node" / "node_modules"))
    if node is None:
        pytest.skip("node is not installed")
    if not (modules / package).is_dir():
        pytest.fail(
            f"node is present but the npm package {package} is not installed: run `make install` (needs npm)"
        )
    return [node, str(ROOT / "tools" / script)], {
        **os.environ,
        "NODE_PATH": str(modules),
        "HRR_NODE_MODULES": str(modules),
    }


def _validate(path: Path) -> None:
    cmd, env = _node_script("gltf-validator", "gltf_validate.js")
    run = subprocess.run(cmd + [str(path)], capture_output=True, text=True, env=env, timeout=120)
    report = json.loads(run.stdout.strip().splitlines()[-1])
    assert run.returncode == 0 and report["errors"] == 0, report


@pytest.mark.client
@pytest.mark.parametrize("tolerance", [0.0, 0.01])
def test_threejs_plays_the_glb_as_the_animation(out_h5, tmp_path, tolerance):
    """three.js (its GLTFLoader and AnimationMixer, in node): every frame within 0.001 mm at
    tolerance 0 and within the tolerance otherwise, the clip's duration, keys on frames, normals
    within 5 degrees (99th percentile) of the frame's own."""
    from hrr_garment.cli.export import main

    cmd, env = _node_script("three", "threejs_check.mjs")
    assert main([str(out_h5), "-o", str(tmp_path / "a.glb"), "--tolerance", str(tolerance * 1000)]) == 0
    anim = read_animation_h5(out_h5)
    with open(tmp_path / "ref.bin", "wb") as fh:  # the layout tools/threejs_check.mjs reads
        fh.write(struct.pack("<iiid", anim.num_frames, anim.vertices.shape[1], len(anim.faces), anim.fps))
        fh.write(anim.vertices.astype("<f4").tobytes() + anim.faces.astype("<u4").tobytes())
    run = subprocess.run(
        cmd + [str(tmp_path / "ref.bin"), str(tmp_path / "a.glb")],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    r = json.loads(run.stdout.strip().splitlines()[-1])
    assert abs(r["duration_s"] - (anim.num_frames - 1) / anim.fps) < 1e-5 and r["keys_on_frames"], r
    assert (
        r["max_vertex_error_mm"] < max(0.001, 1000 * tolerance + 1e-3) and r["normal_error_p99_deg"] < 5.0
    ), r


@pytest.mark.client
@pytest.mark.parametrize("tolerance", [0.0, 0.002])
def test_glb_reloads_to_the_same_vertices_and_validates(out_h5, tmp_path, tolerance):
    from hrr_garment.export.glb import write_glb
    from hrr_garment.export.glb_read import read_glb_keyframes

    anim = read_animation_h5(out_h5)
    report = write_glb(anim, tmp_path / "a.glb", tolerance=tolerance)
    times, verts, faces = read_glb_keyframes(report.path)
    keys = report.keyframes.frames
    assert np.allclose(times, keys / 30.0, atol=1e-6) and np.array_equal(faces, anim.faces)
    assert np.abs(verts - anim.vertices[keys]).max() <= 1e-5
    # every frame, played back as glTF's LINEAR interpolation of the weights, is within the bound
    full = np.zeros_like(anim.vertices, dtype=np.float64)
    full[keys] = verts
    assert np.linalg.norm(interpolate(full, keys) - anim.vertices, axis=-1).max() <= tolerance + 1e-5
    if tolerance > 0:
        assert len(keys) < anim.num_frames
    # the normals a renderer shades with (base + weighted targets, normalised) are those of the
    # morphed positions, recomputed, within a small angle
    from hrr_garment.export.glb_read import read_glb_normals
    from hrr_garment.garment.mesh import vertex_normals

    shaded = read_glb_normals(report.path)
    angle = np.degrees(np.arccos(np.clip((shaded * vertex_normals(verts, faces)).sum(-1), -1, 1)))
    assert shaded.shape == verts.shape and angle.max() < 0.05
    _validate(report.path)


@pytest.mark.client
def test_glb_without_normals_is_smaller_and_has_none(out_h5, tmp_path):
    from hrr_garment.export.glb import write_glb
    from hrr_garment.export.glb_read import read_glb_normals

    anim = read_animation_h5(out_h5)
    with_normals = write_glb(anim, tmp_path / "n.glb", tolerance=0.0)
    without = write_glb(anim, tmp_path / "p.glb", tolerance=0.0, normals=False)
    assert read_glb_normals(without.path) is None and read_glb_normals(with_normals.path) is not None
    assert without.bytes < 0.6 * with_normals.bytes
    _validate(without.path)


def test_vertex_normals_of_known_shapes():
    from hrr_garment.garment.mesh import vertex_normals

    square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    assert np.allclose(vertex_normals(square, faces), [0, 0, 1])
    assert np.allclose(vertex_normals(square, faces[:, ::-1]), [0, 0, -1])  # the winding's side
    # a closed octahedron: every vertex normal points out along its own position
    verts = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    octa = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    assert np.allclose(vertex_normals(verts, octa), verts)
    # batched frames equal frame by frame; rotation and scale carry over; an unused vertex gets +Y
    frames = np.stack([verts, 2 * verts @ np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], float).T])
    assert np.allclose(vertex_normals(frames, octa)[1], vertex_normals(frames[1], octa))
    assert np.allclose(vertex_normals(frames, octa)[1], frames[1] / 2)
    assert np.allclose(vertex_normals(np.r_[square, [[5, 5, 5]]], faces)[4], [0, 1, 0])


@pytest.mark.client
def test_glb_with_body_animates_one_node_per_capsule(out_h5, tmp_path):
    import pygltflib

    from hrr_garment.export.glb import write_glb

    anim = read_animation_h5(out_h5)
    path = write_glb(anim, tmp_path / "b.glb", with_body=True).path
    gltf = pygltflib.GLTF2().load(str(path))
    capsules = [n for n in gltf.nodes if n.name.startswith("capsule_")]
    assert len(capsules) == len(anim.radii)
    paths = sorted(ch.target.path for ch in gltf.animations[0].channels)
    assert paths.count("translation") == paths.count("rotation") == len(anim.radii)
    # the first capsule's animated translation is its end point a in every frame
    ch = next(c for c in gltf.animations[0].channels if c.target.path == "translation")
    acc = gltf.accessors[gltf.animations[0].samplers[ch.sampler].output]
    view = gltf.bufferViews[acc.bufferView]
    data = np.frombuffer(gltf.binary_blob(), np.float32, acc.count * 3, view.byteOffset).reshape(-1, 3)
    assert np.abs(data - anim.capsules[:, 0, 0]).max() < 1e-6
    _validate(path)


# ---------------------------------------------------------------- USD, PC2, OBJ


@pytest.mark.parametrize("suffix", [".usdc", ".usda"])
def test_usd_reloads_with_rate_frames_and_points(out_h5, tmp_path, suffix):
    from pxr import Usd, UsdGeom

    from hrr_garment.export.usd import write_usd

    anim = read_animation_h5(out_h5)
    path = write_usd(anim, tmp_path / f"a{suffix}", with_body=True)
    stage = Usd.Stage.Open(str(path))
    assert stage.GetTimeCodesPerSecond() == 30.0 and stage.GetFramesPerSecond() == 30.0
    assert stage.GetEndTimeCode() - stage.GetStartTimeCode() + 1 == anim.num_frames
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == "Y"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Animation/skirt"))
    points = mesh.GetPointsAttr()
    assert len(points.GetTimeSamples()) == anim.num_frames
    for t in (0, 17, anim.num_frames - 1):
        assert np.abs(np.array(points.Get(t)) - anim.vertices[t]).max() == 0
    assert np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3).tolist() == anim.faces.tolist()
    assert (
        len(UsdGeom.Mesh(stage.GetPrimAtPath("/Animation/body")).GetPointsAttr().GetTimeSamples())
        == anim.num_frames
    )


def test_pc2_round_trip_and_base_obj(out_h5, tmp_path):
    from hrr_garment.errors import InputError
    from hrr_garment.export.pointcache import read_pc2, write_pc2_with_obj
    from hrr_garment.garment.obj import read_obj

    anim = read_animation_h5(out_h5)
    pc2, obj = write_pc2_with_obj(anim, tmp_path / "a.pc2")
    raw = pc2.read_bytes()
    assert raw[:12] == b"POINTCACHE2\0" and len(raw) == 32 + anim.vertices.size * 4
    data, start, rate = read_pc2(pc2)
    assert np.array_equal(data, anim.vertices) and start == 0.0 and rate == 1.0
    v, f, _ = read_obj(obj)
    assert np.abs(v - anim.vertices[0]).max() < 1e-6 and np.array_equal(f, anim.faces)
    (tmp_path / "cut.pc2").write_bytes(raw[:-4])
    with pytest.raises(InputError, match="cut.pc2"):
        read_pc2(tmp_path / "cut.pc2")


def test_obj_sequence_frames_and_stale_frames_removed(out_h5, tmp_path):
    from hrr_garment.export.pointcache import write_obj_sequence
    from hrr_garment.garment.obj import read_obj_vertices

    anim = read_animation_h5(out_h5)
    files = write_obj_sequence(anim, tmp_path / "seq", progress=False)
    assert len(files) == anim.num_frames and files[3].name == "skirt_00003.obj"
    assert np.abs(read_obj_vertices(files[25]) - anim.vertices[25]).max() < 1e-6
    shorter = _write(tmp_path / "short.h5", _animation_arrays(12))
    write_obj_sequence(read_animation_h5(shorter), tmp_path / "seq", progress=False)
    assert len(list((tmp_path / "seq").glob("*.obj"))) == 12
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging folder left


# ---------------------------------------------------------------- hrr-export errors


def test_hrr_export_writes_each_format(out_h5, tmp_path, capsys):
    from hrr_garment.cli.export import main

    for out in ("a.glb", "a.usdc", "a.pc2", "frames"):
        assert main([str(out_h5), "-o", str(tmp_path / out)]) == 0
    text = capsys.readouterr().out
    assert "keyframes of 40 frames" in text and "(obj," in text
    assert (tmp_path / "a.obj").is_file() and len(list((tmp_path / "frames").glob("*.obj"))) == 40


def test_hrr_export_refuses_bad_input_without_output(out_h5, tmp_path, capsys):
    import h5py

    from hrr_garment.cli.export import main

    nan = _animation_arrays()
    nan["vertices"][7, 3, 1] = np.nan
    _write(tmp_path / "nan.h5", nan)
    with h5py.File(tmp_path / "nokey.h5", "w") as f:
        f.create_dataset("vertices", data=np.zeros((2, 3, 3)))
    (tmp_path / "text.h5").write_text("not hdf5")
    # found by tools/fuzz.py: a text frame rate, bytes flipped inside the compressed vertices, NaN joints
    _write(tmp_path / "fps.h5", {**_animation_arrays(), "attrs": {"fps": "{not json"}})
    _write(tmp_path / "chunk.h5", _animation_arrays())
    with h5py.File(tmp_path / "chunk.h5", "r") as f:
        offset = f["vertices"].id.get_chunk_info(3).byte_offset
    data = bytearray((tmp_path / "chunk.h5").read_bytes())
    data[offset + 8 : offset + 200] = bytes(range(192))
    (tmp_path / "chunk.h5").write_bytes(bytes(data))
    joints = _animation_arrays()
    joints["joints"] = joints["joints"].copy()
    joints["joints"][5, 2, 0] = np.inf
    _write(tmp_path / "joints.h5", joints)
    cases = [
        (["fps.h5", "-o", "x.glb"], "the 'fps' attribute must be a frame rate"),
        (["chunk.h5", "-o", "x.glb"], "damaged file, cannot be read"),
        (["joints.h5", "-o", "x.glb"], "/body/joints has non-finite values at frame 5"),
        (["nan.h5", "-o", "x.glb"], "frame 7"),
        (["nokey.h5", "-o", "x.glb"], "missing faces"),
        (["text.h5", "-o", "x.glb"], "not an HDF5 file"),
        (["absent.h5", "-o", "x.glb"], "no such file"),
        ([str(out_h5), "-o", "x.fbx"], "cannot tell the format"),
        ([str(out_h5), "-o", "x.pc2", "--with-body"], "--with-body"),
        ([str(out_h5), "-o", "x.glb", "--tolerance", "-1"], "millimetres >= 0"),
    ]
    for args, message in cases:
        args = [str(tmp_path / a) if a.endswith(".h5") and "/" not in a else a for a in args]
        args = [str(tmp_path / a) if a.startswith("x.") else a for a in args]
        assert main(args) == 2, args
        err = capsys.readouterr().err
        assert message in err, (args, err)
    assert not list(tmp_path.glob("x*")) and not list(tmp_path.glob(".*"))


def test_version1_file_without_body(tmp_path):
    from hrr_garment.errors import InputError
    from hrr_garment.export.glb import write_glb

    arrays = _animation_arrays(10)
    del arrays["capsules"], arrays["radii"]
    anim = read_animation_h5(_write(tmp_path / "v1.h5", arrays))
    assert anim.capsules is None
    write_glb(anim, tmp_path / "ok.glb")
    with pytest.raises(InputError, match="no body capsules"):
        write_glb(anim, tmp_path / "body.glb", with_body=True)
    assert not (tmp_path / "body.glb").exists()
