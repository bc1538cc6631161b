"""Blender: the add-on's zip and file readers, what the exports carry for it, and (client tier)
the exports opened in a real Blender through tools/blender_check.py."""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
import tomllib

from hrr_garment.blender import blender_command
from hrr_garment.export.blender_package import ADDON_FILES, ADDON_SOURCE, addon_zip_bytes
from hrr_garment.garment.mesh import vertex_normals
from tests.scripts import load_script

from .test_export import ROOT, _animation_arrays, _write


@pytest.fixture
def out_h5(tmp_path) -> Path:
    return _write(tmp_path / "out.h5", _animation_arrays())


def _addon_files_module():
    """The add-on's bpy-free reader module, loaded from its file as Blender would load it."""
    return load_script(ADDON_SOURCE / "files.py", "hrr_addon_files")


def test_the_addon_zip_holds_a_blender_extension():
    data = addon_zip_bytes()
    assert data == addon_zip_bytes()  # reproducible: the same bytes on every build
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        assert sorted(zf.namelist()) == sorted(ADDON_FILES)  # the manifest at the root, as 4.2+ wants it
        manifest = tomllib.loads(zf.read("blender_manifest.toml").decode())
        for name in ("__init__.py", "files.py"):
            compile(zf.read(name), name, "exec")  # valid Python for Blender's interpreter
    assert manifest["type"] == "add-on" and manifest["schema_version"] == "1.0.0"
    assert tuple(map(int, manifest["blender_version_min"].split("."))) >= (4, 2, 0)
    assert manifest["license"] == ["SPDX:Apache-2.0"] and manifest["id"].isidentifier()


def test_hrr_blender_addon_writes_the_zip_and_refuses_another_extension(tmp_path):
    from hrr_garment.cli.blender_addon import main

    assert main(["-o", str(tmp_path / "addon.zip")]) == 0
    assert (tmp_path / "addon.zip").read_bytes() == addon_zip_bytes()
    assert main(["-o", str(tmp_path / "addon.txt")]) == 2 and not (tmp_path / "addon.txt").exists()


def test_the_addon_reads_the_timeline_of_our_glb_and_pc2(tmp_path, out_h5):
    from hrr_garment.cli.export import main as export

    files = _addon_files_module()
    assert export([str(out_h5), "-o", str(tmp_path / "a.glb")]) == 0
    assert export([str(out_h5), "-o", str(tmp_path / "a.pc2")]) == 0
    frames = len(_animation_arrays()["vertices"])
    assert files.glb_timeline(str(tmp_path / "a.glb")) == (30.0, frames)
    assert files.pc2_frames(str(tmp_path / "a.pc2")) == frames
    with pytest.raises(ValueError, match="not a GLB"):
        files.glb_timeline(str(tmp_path / "a.pc2"))
    with pytest.raises(ValueError, match="not a PC2"):
        files.pc2_frames(str(tmp_path / "a.obj"))


def _glb_with(path: Path, document: object, claim: int | None = None) -> str:
    """A GLB whose JSON chunk is ``document`` (its length field ``claim`` when given)."""
    body = json.dumps(document).encode()
    body += b" " * (-len(body) % 4)
    header = struct.pack("<5I", 0x46546C67, 2, 20 + len(body), claim or len(body), 0x4E4F534A)
    path.write_bytes(header + body)
    return str(path)


@pytest.mark.parametrize(
    ("document", "words"),
    [
        ([1, 2], "document is not an object"),
        ({"scenes": [{}], "scene": 3}, "scene 3 is not one of its 1 scenes"),
        ({"scenes": {"a": 1}}, "scenes are not a list"),
        ({"scenes": [{}], "scene": "0"}, "scenes are not a list with a whole-number scene"),
        ({"scenes": [7]}, "scene is not an object"),
        ({"scenes": [{"extras": [1]}]}, "scene extras is not an object"),
        ({"scenes": [{"extras": {"fps": float("inf"), "frames": 10}}]}, "frame rate inf"),
        ({"scenes": [{"extras": {"fps": 0, "frames": 10}}]}, "frame rate 0"),
        ({"scenes": [{"extras": {"fps": 30, "frames": 0}}]}, "frame count 0"),
        ({"scenes": [{"extras": {"fps": 30, "frames": 10**12}}]}, "frame count 1000000000000"),
        ({"scenes": [{"extras": {"fps": 30, "frames": True}}]}, "frame count True"),
        ({"scenes": [{"extras": {"fps": "30", "frames": 10}}]}, "frame rate '30'"),
    ],
)
def test_the_addon_refuses_a_glb_out_of_shape_by_name(tmp_path, document, words):
    """Each would have been a Python error inside Blender (an index, a type, inf in the scene's rate,
    a trillion-frame timeline); now one message naming the file, which the operator reports."""
    files = _addon_files_module()
    path = _glb_with(tmp_path / "hostile.glb", document)
    with pytest.raises(ValueError) as err:
        files.glb_timeline(path)
    assert str(err.value).startswith(path) and words in str(err.value)


def test_the_addon_refuses_a_glb_or_pc2_whose_sizes_lie(tmp_path, out_h5):
    from hrr_garment.cli.export import main as export

    files = _addon_files_module()
    with pytest.raises(ValueError, match="claims 4000000000 bytes"):
        files.glb_timeline(_glb_with(tmp_path / "long.glb", {"scenes": [{}]}, claim=4_000_000_000))
    nested = tmp_path / "deep.glb"
    _glb_with(nested, {})
    deep = b"[" * 100_000 + b"]" * 100_000
    nested.write_bytes(struct.pack("<5I", 0x46546C67, 2, 20 + len(deep), len(deep), 0x4E4F534A) + deep)
    with pytest.raises(ValueError, match="nested too deep"):
        files.glb_timeline(str(nested))
    nested.write_bytes(nested.read_bytes()[:20] + b"\xe7" + nested.read_bytes()[21:])
    with pytest.raises(ValueError, match="deep.glb: its JSON chunk is damaged"):
        files.glb_timeline(str(nested))
    assert export([str(out_h5), "-o", str(tmp_path / "a.pc2")]) == 0
    data = (tmp_path / "a.pc2").read_bytes()
    for name, damaged, words in (
        ("cut.pc2", data[:-12], "but it holds"),
        ("zero.pc2", data[:28] + struct.pack("<i", 0) + data[32:], "0 samples is not an animation"),
        ("many.pc2", data[:28] + struct.pack("<i", 2**31 - 1) + data[32:], "is not an animation"),
        ("neg.pc2", data[:16] + struct.pack("<i", -3) + data[20:], "-3 points"),
    ):
        (tmp_path / name).write_bytes(damaged)
        with pytest.raises(ValueError) as err:
            files.pc2_frames(str(tmp_path / name))
        assert words in str(err.value) and str(err.value).startswith(str(tmp_path / name))


def test_a_glb_of_another_tool_has_no_timeline(tmp_path):
    pygltflib = pytest.importorskip("pygltflib")
    gltf = pygltflib.GLTF2(asset=pygltflib.Asset(version="2.0"), scenes=[pygltflib.Scene(nodes=[])], scene=0)
    gltf.save_binary(str(tmp_path / "other.glb"))
    assert _addon_files_module().glb_timeline(str(tmp_path / "other.glb")) is None


def test_exports_carry_what_blender_needs(tmp_path, out_h5):
    """Smoothing in the OBJ, normals on the body's capsules, the rate and length in USD's user
    properties (Blender's USD importer turns them into custom properties)."""
    pygltflib = pytest.importorskip("pygltflib")
    pxr = pytest.importorskip("pxr")
    from hrr_garment.cli.export import main as export

    assert export([str(out_h5), "-o", str(tmp_path / "a.pc2")]) == 0
    obj = (tmp_path / "a.obj").read_text().splitlines()
    assert "s 1" in obj and obj.index("s 1") < next(i for i, line in enumerate(obj) if line.startswith("f "))
    assert export([str(out_h5), "-o", str(tmp_path / "a.glb"), "--with-body"]) == 0
    gltf = pygltflib.GLTF2().load(str(tmp_path / "a.glb"))
    capsules = [m for m in gltf.meshes if m.name.startswith("capsule_")]
    assert capsules and all(m.primitives[0].attributes.NORMAL is not None for m in capsules)
    assert export([str(out_h5), "-o", str(tmp_path / "a.usda")]) == 0
    stage = pxr.Usd.Stage.Open(str(tmp_path / "a.usda"))
    root = stage.GetPrimAtPath("/Animation")
    assert root.GetAttribute("userProperties:fps").Get() == 30.0
    assert root.GetAttribute("userProperties:frames").Get() == len(_animation_arrays()["vertices"])


def test_a_blend_without_blender_is_a_clear_error_and_no_file(tmp_path, out_h5, monkeypatch, capsys):
    from hrr_garment.cli.export import main as export

    monkeypatch.delenv("HRR_BLENDER", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))
    assert export([str(out_h5), "-o", str(tmp_path / "a.blend")]) == 2
    assert "a.blend: writing a .blend needs Blender" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.h5"]


def test_vertex_normals_weigh_faces_by_their_angle():
    """One vertex between a face in z = 0 with a 90 degree corner there and a face in x = 0 with a
    45 degree corner and four times the area: the normal leans 2 : 1 toward the first (by area it
    would lean 4 : 1 toward the second)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 2, 0], [0, 2, 2]], np.float64)
    faces = np.array([[0, 1, 2], [0, 3, 4]])  # normals +Z (corner angle pi/2, area 1/2) and +X (pi/4, area 2)
    expected = np.array([1.0, 0.0, 2.0]) / np.sqrt(5.0)
    assert np.allclose(vertex_normals(v, faces)[0], expected)


# ---------------------------------------------------------------- client tier: a real Blender


@pytest.mark.client
@pytest.mark.tool
def test_blender_plays_our_exports_through_the_addon(tmp_path):
    """Blender 4.2+ through the add-on, and the .blend hrr-export has Blender write: every frame
    within 0.001 mm, the clip's rate and range, per-frame normals within 5 degrees (99th
    percentile) of the frame's own."""
    blender = blender_command()
    if blender is None:
        pytest.skip(
            "no Blender: set HRR_BLENDER to the blender program or to a Python with bpy (pip install bpy)"
        )
    from hrr_garment.cli.blender_addon import main as addon
    from hrr_garment.cli.export import main as export

    arrays = _animation_arrays()
    out = _write(tmp_path / "out.h5", arrays)
    files = [tmp_path / "a.glb", tmp_path / "a.usdc", tmp_path / "a.pc2", tmp_path / "a.blend"]
    for f in files:
        assert (
            export(
                [str(out), "-o", str(f)] + (["--tolerance", "0"] if f.suffix in (".glb", ".blend") else [])
            )
            == 0
        )
    assert addon(["-o", str(tmp_path / "addon.zip")]) == 0
    np.savez(tmp_path / "ref.npz", vertices=arrays["vertices"], faces=arrays["faces"], fps=30.0)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender"))  # not the user's own Blender
    run = subprocess.run(
        blender
        + [
            str(ROOT / "tools" / "blender_check.py"),
            "--",
            str(tmp_path / "ref.npz"),
            *map(str, files),
            f"--addon={tmp_path / 'addon.zip'}",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    results = [json.loads(line) for line in run.stdout.splitlines() if line.startswith("{")]
    assert run.returncode == 0 and len(results) == 4, run.stdout[-2000:] + run.stderr[-2000:]
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary file left
    for r in results:
        assert "error" not in r, r
        assert r["rate_ok"] and r["range_ok"] and r["smooth_faces"] == 1.0, r
        assert r["max_vertex_error_mm"] < 0.001 and r["normal_error_p99_deg"] < 5.0, r


@pytest.mark.client
@pytest.mark.tool
def test_blender_reports_a_damaged_export_through_the_addon(tmp_path, out_h5):
    """In a real Blender, the add-on's import of a GLB whose timeline is inf, or of a PC2 cut short,
    is refused with one message naming the file (the operator's error report; before, an
    OverflowError escaped into Blender), and an intact export imports."""
    blender = blender_command()
    if blender is None:
        pytest.skip(
            "no Blender: set HRR_BLENDER to the blender program or to a Python with bpy (pip install bpy)"
        )
    from hrr_garment.cli.blender_addon import main as addon
    from hrr_garment.cli.export import main as export

    assert addon(["-o", str(tmp_path / "addon.zip")]) == 0
    assert export([str(out_h5), "-o", str(tmp_path / "a.glb")]) == 0
    assert export([str(out_h5), "-o", str(tmp_path / "a.pc2")]) == 0
    infinite = _glb_with(
        tmp_path / "inf.glb",
        {"asset": {"version": "2.0"}, "scenes": [{"extras": {"fps": 1e999, "frames": 3}}]},
    )
    (tmp_path / "cut.pc2").write_bytes((tmp_path / "a.pc2").read_bytes()[:-12])
    (tmp_path / "cut.obj").write_bytes((tmp_path / "a.obj").read_bytes())
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender"))
    script = str(ROOT / "tools" / "blender_addon_import.py")

    def run(path):
        done = subprocess.run(
            blender + [script, "--", f"--addon={tmp_path / 'addon.zip'}", str(path)],
            capture_output=True,
            text=True,
            timeout=300,
            env=env,
        )
        return done.returncode, done.stderr

    assert run(tmp_path / "a.glb")[0] == 0
    for path, words in ((infinite, "frame rate inf"), (tmp_path / "cut.pc2", "but it holds")):
        rc, err = run(path)
        assert rc == 2 and "Traceback" not in err, err[-2000:]
        assert str(path) in err.splitlines()[-1] and words in err.splitlines()[-1]
