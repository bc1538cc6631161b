"""FBX motion through Blender (hrr_garment.motion.fbx, hrr_garment.blender): the errors without a
Blender, and (client tier) a CMU clip written as FBX by Blender read back as the BVH reads."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from hrr_garment.blender import blender_command
from hrr_garment.errors import MotionError
from hrr_garment.motion.io import load_motion

# run by Blender: a BVH as Blender's importer reads it, written by its FBX exporter
BVH_TO_FBX = """
import sys
import bpy
source, target = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_anim.bvh(filepath=source, update_scene_fps=True, update_scene_duration=True)
bpy.ops.export_scene.fbx(filepath=target, bake_anim=True, add_leaf_bones=False)
"""


def test_fbx_without_a_blender_names_what_it_needs(tmp_path, monkeypatch):
    clip = tmp_path / "clip.fbx"
    clip.write_bytes(b"Kaydara FBX Binary  \x00")
    monkeypatch.delenv("HRR_BLENDER", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # no blender on it
    with pytest.raises(MotionError, match=r"clip.fbx: reading FBX needs Blender \(4.2 or later\)"):
        load_motion(clip)
    monkeypatch.setenv("HRR_BLENDER", str(tmp_path / "blender"))  # named, but not there
    with pytest.raises(MotionError, match="is not there"):
        load_motion(clip)


def test_an_fbx_take_cannot_be_chosen_by_name(tmp_path):
    clip = tmp_path / "clip.fbx"
    clip.write_bytes(b"Kaydara FBX Binary  \x00")
    with pytest.raises(MotionError, match="named animations"):
        load_motion(clip, animation="Take 001")


@pytest.mark.client
def test_a_clip_through_blenders_fbx_reads_as_its_bvh(tmp_path, mocap_dir):
    """CMU 02_01 written as FBX by Blender: the same frames, joints within a few millimetres of the
    BVH's (Blender drops the end sites the BVH grounds and measures with); a damaged FBX is a clear
    error naming the file."""
    command = blender_command()
    if command is None:
        pytest.skip(
            "no Blender: set HRR_BLENDER to the blender program or to a Python with bpy (pip install bpy)"
        )
    script, fbx = tmp_path / "bvh_to_fbx.py", tmp_path / "02_01.fbx"
    script.write_text(BVH_TO_FBX)
    subprocess.run(
        [*command, str(script), "--", str(mocap_dir / "cmu" / "02_01.bvh"), str(fbx)],
        check=True,
        capture_output=True,
        timeout=600,
    )
    bvh, from_fbx = load_motion(mocap_dir / "cmu" / "02_01.bvh"), load_motion(fbx)
    assert from_fbx.num_frames == bvh.num_frames and from_fbx.source == str(fbx)
    local = [m.joint_positions - m.root_translation[:, None] for m in (bvh, from_fbx)]
    gap = np.linalg.norm(local[0] - local[1], axis=-1)
    assert gap.mean() < 0.002 and gap.max() < 0.02  # metres
    assert np.abs(bvh.root_translation - from_fbx.root_translation).max() < 0.02
    damaged = tmp_path / "damaged.fbx"
    damaged.write_bytes(fbx.read_bytes()[: len(fbx.read_bytes()) // 3])
    with pytest.raises(MotionError, match="damaged.fbx: "):
        load_motion(damaged)
