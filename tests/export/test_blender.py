"""Blender: the add-on's zip and file readers, what the exports carry for it, and (client tier)
the exports opened in a real Blender through tools/blender_check.py."""

from __future__ import annotations

import importlib.util
import io
import json
import os
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
import tomllib

from hrr_garment.blender import blender_command
from hrr_garment.export.blender_package import ADDON_FILES, ADDON_SOURCE, addon_zip_bytes
from hrr_garment.garment.mesh import vertex_normals

from .test_export import ROOT, _animation_arrays, _write


@pytest.fixture
def out_h5(tmp_path) -> Path:
    return _write(tmp_path / "out.h5", _animation_arrays())


def _addon_files_module():
    """The add-on's bpy-free reader module, loaded from its file as Blender would load it."""
    spec = importlib.util.spec_from_file_location("hrr_addon_files", ADDON_SOURCE / "files.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
