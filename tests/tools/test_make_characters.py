"""tools/studies/make_characters.py: a restyled body keeps its weights' blend (an identity style
changes nothing; a uniform one scales about the pelvis), and the GLB it writes reads back as the
character it was, Mixamo-named joints, four skin weights and all, and fits."""

from __future__ import annotations

import numpy as np
import pytest

from tests.scripts import load_script

pytest.importorskip("pygltflib")


def _tool():
    return load_script("tools/studies/make_characters.py")


def _body():
    """The test mannequin's surface with smooth weights: each vertex on its three nearest joints."""
    from tests.body.test_character import _mannequin

    vertices, faces, joints = _mannequin()
    d = np.linalg.norm(vertices[:, None] - joints[None], axis=-1)
    near = np.argsort(d, axis=1)[:, :3]
    weights = np.zeros((len(vertices), len(joints)))
    np.put_along_axis(weights, near, 1.0 / (np.take_along_axis(d, near, 1) + 0.02), 1)
    return vertices, faces, joints, weights / weights.sum(1, keepdims=True)


def test_a_restyling_moves_the_mesh_by_its_joints_blend():
    from hrr_garment.motion.skeleton import JOINT_NAMES

    tool = _tool()
    vertices, _, joints, weights = _body()
    same, same_joints = tool.restyled(vertices, joints, weights, tool.Style({}))
    assert np.allclose(same, vertices) and np.allclose(same_joints, joints)
    every = {name: 1.2 for name in JOINT_NAMES}
    grown, grown_joints = tool.restyled(vertices, joints, weights, tool.Style({}, bones=every, girth=every))
    pelvis = joints[0]
    assert np.allclose(grown_joints - pelvis, 1.2 * (joints - pelvis))
    assert np.allclose(grown - pelvis, 1.2 * (vertices - pelvis))  # one scale about the pelvis
    head = tool.restyled(vertices, joints, weights, tool.Style({}, girth={"head": 1.5}))[0]
    moved = np.linalg.norm(head - vertices, axis=1) > 1e-9
    assert np.array_equal(moved, weights[:, JOINT_NAMES.index("head")] > 0)  # only the head's flesh


def test_the_written_character_reads_back_and_fits(tmp_path):
    from hrr_garment.body.character import read_character
    from hrr_garment.body.fit import fit_body

    tool = _tool()
    vertices, faces, joints, weights = _body()
    path = tmp_path / "hero.glb"
    tool.write_character(path, vertices, faces, joints, weights)
    character = read_character(path)
    assert np.abs(character.vertices - vertices).max() < 1e-5
    assert np.abs(character.joints - joints).max() < 1e-5
    assert np.array_equal(character.faces, faces)
    assert np.abs(character.weights - weights).max() < 1e-6  # three joints a vertex: all four slots kept
    fitted = fit_body(character.vertices, character.joints)
    assert 1.0 < fitted.stature < 2.2
