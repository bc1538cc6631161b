"""Outputs never destroy inputs: an output that is one of the command's inputs, or whose extension
names another format than the one written, is refused before anything is written, and no hidden
temporary file is left behind (issue 48's data-loss reproducers 10 and 11)."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from hrr_garment import synthesize
from hrr_garment.motion.bvh_write import write_bvh
from hrr_garment.motion.io import load_motion, save_motion
from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS

FIXTURES = Path(__file__).parents[1] / "fixtures" / "out-31b4ef9"


def _listing(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


def test_a_motion_is_written_as_npz_only_and_over_a_bvh_never(tmp_path, capsys):
    from hrr_garment.cli.motion import main

    motion = synthesize("walk", seconds=1.0, seed=0)
    clip = tmp_path / "clip.bvh"
    write_bvh(
        clip,
        list(JOINT_NAMES),
        list(PARENTS),
        CANONICAL.offsets,
        motion.local_rotations.astype(np.float64),
        motion.root_translation,
        1 / 30,
    )
    before = _listing(tmp_path)
    assert main(["synth", "walk", "-o", str(clip)]) == 2
    assert "clip.bvh" in capsys.readouterr().err
    assert _listing(tmp_path) == before  # the BVH as it was, and nothing hidden beside it
    assert main(["synth", "walk", "--seconds", "1", "-o", str(tmp_path / "walk.npz")]) == 0
    again = load_motion(tmp_path / "walk.npz")  # an npz, not a renamed empty file
    assert again.num_frames == 30 and sorted(p.name for p in tmp_path.iterdir()) == ["clip.bvh", "walk.npz"]
    with pytest.raises(Exception, match="native motion"):
        save_motion(again, tmp_path / "walk.bvh")
    assert main(["features", str(clip), "-o", str(clip)]) == 2  # the features over their own input
    assert _listing(tmp_path)["clip.bvh"] == before["clip.bvh"]


@pytest.mark.parametrize("args", [["--to", "glb"], ["--to", "pc2"], ["--to", "usd"], ["--to", "obj"]])
def test_an_export_over_its_own_animation_is_refused(tmp_path, capsys, args):
    from hrr_garment.cli.export import main

    anim = tmp_path / "in.h5"
    shutil.copy(FIXTURES / "auto.h5", anim)
    before = _listing(tmp_path)
    assert main([str(anim), *args, "-o", str(anim)]) == 2
    assert "in.h5" in capsys.readouterr().err and _listing(tmp_path) == before


def test_an_output_that_is_the_input_by_another_name_is_refused(tmp_path, capsys):
    from hrr_garment.cli.animate import main as animate
    from hrr_garment.cli.export import main as export

    anim = tmp_path / "in.h5"
    shutil.copy(FIXTURES / "auto.h5", anim)
    (tmp_path / "link.glb").symlink_to(anim)  # the right extension, but the input itself
    assert export([str(anim), "-o", str(tmp_path / "link.glb")]) == 2
    assert "is the input" in capsys.readouterr().err
    assert (tmp_path / "link.glb").is_symlink() and (tmp_path / "in.h5").read_bytes() == (
        FIXTURES / "auto.h5"
    ).read_bytes()
    clip = tmp_path / "walk.npz"
    save_motion(synthesize("walk", seconds=1.0, seed=0), clip)
    (tmp_path / "out.h5").symlink_to(clip)
    before = clip.read_bytes()
    assert animate([str(clip), "-o", str(tmp_path / "out.h5"), "--model", str(tmp_path)]) == 2
    assert "is the input" in capsys.readouterr().err and clip.read_bytes() == before


@pytest.mark.parametrize("far", [3e38, 1e30, 2.0])
@pytest.mark.parametrize("to", ["glb", "pc2", "obj"])
def test_an_export_of_absurd_cloth_is_refused_as_hrr_animate_would(tmp_path, capsys, far, to):
    """Exporters apply hrr-animate's reach check (issue 48, reproducers 8 and 9): a vertex at 3e38
    or 1e30, or 2 m from every joint, is not cloth on a body."""
    import h5py

    from hrr_garment.cli.export import main

    anim = tmp_path / "in.h5"
    shutil.copy(FIXTURES / "auto.h5", anim)
    with h5py.File(anim, "r+") as f:
        vertices = f["vertices"][()]
        joints = f["body/joints"][()]
        vertices[3, 7] = joints[3, 0] + np.array([far, 0.0, 0.0], np.float32)
        f["vertices"][...] = vertices
    before = _listing(tmp_path)
    output = tmp_path / {"glb": "out.glb", "pc2": "out.pc2", "obj": "frames"}[to]
    assert main([str(anim), "--to", to, "-o", str(output)]) == 2
    assert "from the body at frame 3" in capsys.readouterr().err and _listing(tmp_path) == before
    assert not output.exists()


def test_the_new_doors_never_write_over_what_they_read(tmp_path, capsys):
    """Issue 88: a joint map, a clip given as --check (under the name of the graph's companion
    tensors) and an attached-vertex list given again as the output, each refused, each untouched."""
    from hrr_garment.cli.body import main as body
    from hrr_garment.cli.export_model import main as export_model
    from hrr_garment.cli.simulate import main as simulate
    from tests.body.test_character import Layout, _mannequin, write_skinned

    vertices, faces, joints = _mannequin()
    write_skinned(tmp_path / "hero.glb", vertices, faces, joints)
    joint_map = tmp_path / "map.json"
    joint_map.write_text(json.dumps(dict(zip(JOINT_NAMES, Layout().names))))  # the whole rig, named
    before = _listing(tmp_path)
    assert body(["fit", str(tmp_path / "hero.glb"), "--joint-map", str(joint_map), "-o", str(joint_map)]) == 2
    err = capsys.readouterr().err
    assert "map.json: is the input" in err and _listing(tmp_path) == before
    clip = tmp_path / "walk.tensors.npz"
    save_motion(synthesize("walk", seconds=1.0, seed=0), clip)
    before = _listing(tmp_path)
    args = ["--model", str(FIXTURES.parent / "bundle-31b4ef9"), "--onnx", "--check", str(clip)]
    assert export_model([*args, "-o", str(tmp_path / "walk.onnx")]) == 2
    assert "is the input" in capsys.readouterr().err and _listing(tmp_path) == before
    indices = tmp_path / "idx.h5"
    indices.write_text("0 1 2\n")
    args = ["--garment", "skirt", "--preset", "tiny", "--attached-file", str(indices), "-o", str(indices)]
    assert simulate(args) == 2
    assert "is the input" in capsys.readouterr().err and indices.read_text() == "0 1 2\n"
