"""body.json's own mesh (format 2): a skinned mesh round-trips and is the record's visible body; a
body without one is written as version 1 wrote it and version 1 files still load; a bad mesh is
refused naming the file; the weights kept sparse lose only what lies beyond each vertex's four
largest."""

import json
from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.body import body_file, mesh_record
from hrr_garment.body.body_file import body_to_dict, read_body, write_body
from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.body.mesh_record import BodyMesh, dense_weights, sparse_weights
from hrr_garment.body.retarget import motion_on_body
from hrr_garment.body.skinned_body import skinned_body, visible_body
from hrr_garment.errors import InputError
from hrr_garment.motion.synth import synthesize
from tests.body.test_skinned_body import _Rest


def _mesh(seed: int = 0) -> BodyMesh:
    """The mannequin's capsule surface, each vertex skinned to its two nearest joints."""
    rest = _Rest()
    d = np.linalg.norm(rest.vertices[:, None] - rest.joints[None], axis=-1)
    share = np.random.default_rng(seed).random(len(d))
    weights = np.zeros_like(d)
    np.put_along_axis(weights, np.argsort(d, 1)[:, :2], np.stack([share, 1.0 - share], 1), 1)
    return BodyMesh.of(rest.vertices, rest.faces, rest.joints, weights)


def _record(mesh: BodyMesh | None = None):
    return replace(mannequin_record(), mesh=mesh or _mesh())


def test_a_mesh_round_trips_and_is_the_visible_body(tmp_path):
    mesh = _mesh()
    record = _record(mesh)
    path = write_body(tmp_path / "hero.json", record)
    text = path.read_text()
    assert json.loads(text)["format_version"] == 2
    assert text.count("\n") > len(mesh.vertices) + len(mesh.faces)  # a row a line, readable
    back = read_body(path)
    for name in ("vertices", "faces", "joints", "skin_joints", "skin_weights", "weights"):
        assert np.array_equal(getattr(back.mesh, name), getattr(mesh, name))  # to the bit: the same key
    rest = _Rest()
    assert (
        np.abs(mesh.vertices - rest.vertices).max() <= 5e-7
        and np.abs(mesh.joints - rest.joints).max() <= 5e-7
    )
    # posed on a walk, the file's visible body is the mesh it was written from
    visible = visible_body(back)
    assert visible is visible_body(back)  # built once per record
    expected = skinned_body(DEFAULT_BODY.skeleton, mesh, mesh.weights)
    walk = motion_on_body(synthesize("walk", 0.5, seed=0), back)
    posed = visible.pose(walk.global_rotations, walk.joint_positions)
    assert np.abs(posed - expected.pose(walk.global_rotations, walk.joint_positions)).max() < 1e-5
    # the same content read from a dataset's or an out.h5's attribute (body_to_dict's JSON)
    again = body_file.body_from_dict(json.loads(json.dumps(body_to_dict(back))), "data.h5 (body 'hero')")
    assert (
        np.array_equal(again.mesh.faces, back.mesh.faces) and again.mesh.vertices.shape == mesh.vertices.shape
    )


def test_a_body_without_a_mesh_is_version_1_and_version_1_files_load(tmp_path):
    record = mannequin_record()
    data = body_to_dict(record)
    assert data["format_version"] == 1 and "mesh" not in data  # as version 1 wrote it, hashes unchanged
    old = tmp_path / "old.json"
    old.write_text(json.dumps(data))
    back = read_body(old)
    assert back.mesh is None and visible_body(back) is None
    assert np.array_equal(back.body.radii, record.body.radii)
    data["mesh"] = mesh_record.mesh_to_dict(_mesh())
    old.write_text(json.dumps(data))
    with pytest.raises(InputError, match="format_version 1 holds no 'mesh'"):
        read_body(old)


def _refused(tmp_path, change, message: str) -> None:
    data = body_to_dict(_record())
    change(data["mesh"])
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))  # NaN written as Python's json writes it
    with pytest.raises(InputError, match=message) as err:
        read_body(path)
    assert str(path) in str(err.value)


def _put(key, value):
    return lambda m: m.__setitem__(key, value)


def test_bad_meshes_are_refused_naming_the_file(tmp_path, monkeypatch):
    def face_out_of_range(m):
        m["faces"][3][1] = len(m["vertices"])

    def nan_vertex(m):
        m["vertices"][5][2] = float("nan")

    def weights_over_one(m):
        m["skin_weights"][7] = [w * 1.5 for w in m["skin_weights"][7]]

    def negative_weight(m):
        m["skin_weights"][7] = [1.5, -0.5]

    def short_weights(m):
        m["skin_weights"].pop()

    def ragged(m):
        m["vertices"][2] = [0.0, 1.0]

    def joint_out_of_range(m):
        m["skin_joints"][0][0] = 22

    cases = [
        (face_out_of_range, "faces must index its"),
        (nan_vertex, "vertices must be finite"),
        (weights_over_one, "sum to 1.*vertex 7"),
        (negative_weight, "non-negative.*vertex 7"),
        (short_weights, r"skin_joints \(\d+, 2\) and skin_weights \(\d+, 2\)"),
        (ragged, r"vertices must be a list of \d+ rows of 3 numbers"),
        (joint_out_of_range, "canonical joints"),
        (_put("faces", [[0.5, 1, 2]]), "faces must be a list of 1 rows of 3 integers"),
        (_put("joints", [[0.0, 0.0, 0.0]] * 21), "the 22 canonical joints"),
        (_put("vertices", "many"), "vertices must be a list"),
        (_put("skin_weights", [["1", 0]] * 3), "skin_weights must be a list of equal rows of numbers"),
    ]
    for change, message in cases:
        _refused(tmp_path, change, message)
    # sizes are bounded before numpy reads a list, and a file before it is parsed
    monkeypatch.setattr(mesh_record, "MAX_MESH_VERTICES", 10)
    _refused(tmp_path, lambda m: None, "at most 10 rows")
    path = tmp_path / "bad.json"
    monkeypatch.setattr(body_file, "MAX_FILE_BYTES", 1000)
    with pytest.raises(InputError, match="more than a body file may be"):
        read_body(path)
    data = body_to_dict(_record())
    data["mesh"] = [1, 2, 3]
    with pytest.raises(InputError, match="'mesh' must be an object"):
        body_file.body_from_dict(data, "x.json")


def test_sparse_weights_keep_the_four_largest_renormalised():
    rng = np.random.default_rng(3)
    weights = rng.random((50, 22)) * (rng.random((50, 22)) < 0.3)
    weights[:, 0] += 1e-3  # none empty
    weights /= weights.sum(1, keepdims=True)
    joints, kept = sparse_weights(weights)
    assert joints.shape == (50, 4) and np.allclose(kept.sum(1), 1.0)
    fourth = np.sort(weights, 1)[:, -4]
    assert (np.take_along_axis(weights, joints, 1) >= fourth[:, None] - 1e-12).all()
    dense = dense_weights(joints, kept)
    assert np.allclose(dense.sum(1), 1.0) and ((dense > 0).sum(1) <= 4).all()
    # a mesh with fewer influences keeps no more columns than it needs, and loses nothing
    two = _mesh().weights
    joints, kept = sparse_weights(two)
    assert joints.shape[1] == 2 and np.allclose(dense_weights(joints, kept), two)
