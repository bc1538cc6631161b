"""A character file's own skinned mesh in the GLB: hrr-animate --body character.glb, then hrr-export
--character character.glb. The skeleton in the GLB plays the joints out.h5 holds; the mesh skinned
by glTF's rule stays on the character's body; a T-pose frame gives back the file's mesh; an
animation on another body, or from before format 4, is refused."""

from pathlib import Path

import numpy as np
import pytest

from hrr_garment.body.capsules import frames_signed_distance
from hrr_garment.data.animation_file import read_animation_h5
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.skeleton import CANONICAL, JOINT_INDEX, REST_PELVIS_HEIGHT
from hrr_garment.motion.synth import synthesize
from tests.body.test_character import _mannequin, write_skinned
from tests.export.test_export import _animation_arrays, _validate, _write

pygltflib = pytest.importorskip("pygltflib")


def _skinned_frames(path) -> tuple[np.ndarray, np.ndarray]:
    """Each frame of the GLB's character, skinned as glTF says: joints (T, 22, 3), vertices (T, V, 3)."""
    from hrr_garment.export.glb_read import read_glb_character

    joints, vertices, _ = read_glb_character(path)
    return joints, vertices


@pytest.fixture
def out_h5(tmp_path):
    """An out.h5 of synthetic arrays, without the skeleton's motion (as before format 4)."""
    return _write(tmp_path / "out.h5", _animation_arrays())


@pytest.fixture(scope="module")
def character_glb(tmp_path_factory):
    """A character built here (the mannequin's capsule surface, 1.05 times larger, on a Mixamo-named
    skeleton) as a GLB."""
    root = tmp_path_factory.mktemp("character")
    vertices, faces, joints = _mannequin(1.05)
    write_skinned(root / "hero.glb", vertices, faces, joints)
    return root / "hero.glb"


@pytest.fixture(scope="module")
def lopsided_glb(tmp_path_factory):
    """The same character with its left hip joint 4 mm further out than its right, as a rig made by
    hand has it: nearly symmetric, so the body it is fitted to is made exactly so to play a clip."""
    root = tmp_path_factory.mktemp("lopsided")
    vertices, faces, joints = _mannequin(1.05)
    joints[JOINT_INDEX["l_hip"], 0] += 0.004
    write_skinned(root / "lopsided.glb", vertices, faces, joints)
    return root / "lopsided.glb"


def test_the_character_plays_the_clip_in_the_glb_on_its_own_mesh(trained, character_glb, tmp_path, capsys):
    from hrr_garment.cli.export import main as export_main
    from hrr_garment.export.character import skinned_character
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    animator = Animator.load(root / "model")
    with pytest.warns(UserWarning, match="animating it anyway"):  # the tiny model knows the mannequin alone
        anim = animator.animate(synthesize("walk_curve", 1.0, seed=5), body=character_glb, allow_outside=True)
    anim.save(tmp_path / "out.h5")
    assert (
        export_main(
            [
                str(tmp_path / "out.h5"),
                "-o",
                str(tmp_path / "hero_dress.glb"),
                "--tolerance",
                "0",
                "--character",
                str(character_glb),
            ]
        )
        == 0
    )
    saved = read_animation_h5(tmp_path / "out.h5")
    joints, skinned = _skinned_frames(tmp_path / "hero_dress.glb")
    assert np.abs(joints - saved.joints).max() < 1e-4  # the GLB's skeleton is the animation's
    character = skinned_character(character_glb)
    a, b = character.record.body.pose_motion(anim.skeleton)
    gap = np.abs(frames_signed_distance(skinned, a, b, character.record.body.radii)[0])
    assert (
        np.median(gap) < 0.01 and np.quantile(gap, 0.95) < 0.04
    )  # the mesh stays on the body it was fitted to
    _validate(tmp_path / "hero_dress.glb")
    _renders_both(tmp_path / "hero_dress.glb", tmp_path / "hero.png", capsys)


def _renders_both(glb, png, capsys) -> None:
    """tools/render_glb.py draws the garment and the character's skin from the GLB alone, and says
    how much of the garment lies inside the mesh on each frame drawn."""
    import runpy
    import sys

    from PIL import Image

    argv = sys.argv
    sys.argv = ["render_glb.py", str(glb), "-o", str(png), "--frames", "0", "5", "--size", "160"]
    try:
        runpy.run_path(str(Path(__file__).parents[2] / "tools" / "render_glb.py"), run_name="__main__")
    finally:
        sys.argv = argv
    pixels = np.asarray(Image.open(png).convert("RGB")).reshape(-1, 3).astype(int)
    assert pixels.shape[0] == 2 * 160 * 160
    garment = (pixels[:, 2] > pixels[:, 0] + 40).sum()  # bluish
    skin = (pixels[:, 0] > pixels[:, 2] + 30).sum()  # the skin's warm tone
    assert garment > 500 and skin > 500, (garment, skin)
    printed = capsys.readouterr().out
    assert "frame 0, " in printed and "frame 5, " in printed and "inside the mesh" in printed


def test_a_lopsided_character_is_exported_on_the_skeleton_its_clip_was_played_by(trained, lopsided_glb):
    """hrr-export refuses an out.h5 whose skeleton is not the character's: the character a clip is
    played by stands on its fit made exactly symmetric, so the export must stand on that one too."""
    from hrr_garment.body.character import character_body
    from hrr_garment.export.character import skinned_character
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    with pytest.warns(UserWarning, match="animating it anyway"):
        body = Animator.load(root / "model").body(lopsided_glb, allow_outside=True)
    played = body.play(synthesize("walk", 0.2, seed=1)).skeleton.offsets
    fitted = character_body(lopsided_glb)[0].skeleton.offsets
    assert np.abs(fitted - played).max() > 1e-3  # the fit itself is lopsided by millimetres
    assert np.array_equal(skinned_character(lopsided_glb).record.skeleton.offsets, played)


def test_a_t_pose_frame_gives_back_the_files_own_mesh(trained, character_glb, tmp_path):
    """In the T-pose (every local rotation the identity) the skinned mesh is the file's bind-pose
    mesh, only moved with the pelvis: the bind matrices are the fitted skeleton's."""
    from hrr_garment.export.character import skinned_character
    from hrr_garment.export.glb import write_glb
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    animator = Animator.load(root / "model")
    still = Motion(
        np.broadcast_to(np.eye(3), (8, 22, 3, 3)).copy(),
        np.tile([0.0, REST_PELVIS_HEIGHT, 0.3], (8, 1)),
        30.0,
        skeleton=CANONICAL,
    )
    with pytest.warns(UserWarning):
        animator.animate(still, body=character_glb, allow_outside=True).save(tmp_path / "still.h5")
    character = skinned_character(character_glb)
    write_glb(
        read_animation_h5(tmp_path / "still.h5"), tmp_path / "still.glb", tolerance=0, character=character
    )
    _, skinned = _skinned_frames(tmp_path / "still.glb")
    moved = skinned[3] - character.vertices
    assert (
        np.abs(moved - moved.mean(0)).max() < 1e-4 and np.linalg.norm(moved.mean(0) - [0.0, 0.0, 0.3]) < 0.05
    )


def test_an_animation_on_another_body_or_without_a_skeleton_is_refused(
    trained, out_h5, character_glb, tmp_path, capsys
):
    """An out.h5 animated on the mannequin: the character's bones differ, and the export says how to
    fix it; one without the skeleton's motion (before format 4) cannot pose the character."""
    from hrr_garment.cli.export import main as export_main
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    Animator.load(root / "model").animate(synthesize("walk", 0.5, seed=1)).save(tmp_path / "mannequin.h5")
    assert (
        export_main(
            [str(tmp_path / "mannequin.h5"), "-o", str(tmp_path / "x.glb"), "--character", str(character_glb)]
        )
        != 0
    )
    err = capsys.readouterr().err
    assert (
        "another body than hero.glb's" in err
        and "--body hero.glb" in err
        and not (tmp_path / "x.glb").exists()
    )
    assert export_main([str(out_h5), "-o", str(tmp_path / "x.glb"), "--character", str(character_glb)]) != 0
    assert "carries no skeleton motion" in capsys.readouterr().err
    assert export_main([str(out_h5), "-o", str(tmp_path / "x.usda"), "--character", str(character_glb)]) != 0
    assert "--character is for glb" in capsys.readouterr().err


def test_a_vertex_of_few_influences_names_joint_zero_in_its_empty_slots():
    """glTF: a joint slot of weight 0 names joint 0 (the validator warns of any other); the kept
    weights are the heaviest, renormalised."""
    from hrr_garment.export.character import top_influences

    weights = np.zeros((3, 22))
    weights[0, [5, 9]] = [0.75, 0.25]
    weights[1, 3] = 1.0
    weights[2, [1, 2, 4, 7, 8]] = [0.3, 0.3, 0.2, 0.15, 0.05]
    joints, kept = top_influences(weights)
    assert joints[0].tolist() == [5, 9, 0, 0] and kept[0].tolist() == [0.75, 0.25, 0.0, 0.0]
    assert joints[1].tolist() == [3, 0, 0, 0]
    assert joints[2].tolist() == [1, 2, 4, 7] and np.isclose(kept[2].sum(), 1.0)
