"""A body fitted to a mesh: skeleton lengths, capsule radii, the fit's report, and body.json."""

import json
from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.body.body_file import read_body, write_body
from hrr_garment.body.capsules import (
    DEFAULT_BODY,
    BodyModel,
    body_mesh,
    capsule_signed_distance,
    rest_joint_positions,
)
from hrr_garment.body.fit import body_skeleton, fit_body, scaled_capsules, shortest_arc
from hrr_garment.body.parametric import BodyShape
from hrr_garment.errors import InputError
from hrr_garment.motion.skeleton import REST_OFFSETS, Skeleton


def _surface(body: BodyModel, joints: np.ndarray) -> np.ndarray:
    """The vertices of the capsules' union surface (a mesh has no inside), posed on ``joints``."""
    rot = np.broadcast_to(np.eye(3), (1, len(joints), 3, 3))
    a, b = body.pose(rot, joints[None])
    v, _ = body_mesh(a[0], b[0], body.radii, 32, 16)
    return v[capsule_signed_distance(v, a[0], b[0], body.radii)[0] > -1e-6]


def test_the_mannequins_own_surface_fits_back_to_the_mannequin():
    joints = rest_joint_positions()
    fitted = fit_body(_surface(DEFAULT_BODY, joints), joints)
    assert np.allclose(fitted.skeleton.offsets, REST_OFFSETS, atol=1e-6)
    assert np.allclose(fitted.body.radii, DEFAULT_BODY.radii, atol=1e-6)
    assert fitted.report.mean_mm < 1e-6 and fitted.report.outside_1cm == 0 and fitted.report.inside_1cm == 0
    assert fitted.pelvis_height == pytest.approx(
        0.965, abs=1e-3
    )  # the foot capsules reach 8.5 cm below the ankles


def test_a_longer_fuller_body_is_recovered():
    """Bones 12 % longer and capsules 25 % fuller: the fit finds the lengths and the radii."""
    longer = Skeleton(offsets=(REST_OFFSETS * 1.12).astype(np.float32))
    joints = longer.rest_positions(np.array([0.0, 1.1, 0.0]))
    fuller = scaled_capsules(longer, joints).scaled(1.25)
    fitted = fit_body(_surface(fuller, joints), joints)
    assert np.allclose(fitted.skeleton.offsets, longer.offsets, atol=1e-5)
    assert np.allclose(fitted.body.radii, fuller.radii, atol=2e-3)
    assert fitted.report.p95_mm < 3.0


def test_the_skeleton_keeps_canonical_directions_with_the_meshs_lengths():
    joints = rest_joint_positions().copy()
    joints[18] += [0.0, -0.1, 0.0]  # the left elbow lower: an A-pose arm, and a longer upper arm
    skeleton = body_skeleton(joints)
    canonical = REST_OFFSETS[18] / np.linalg.norm(REST_OFFSETS[18])
    assert np.allclose(skeleton.offsets[18] / np.linalg.norm(skeleton.offsets[18]), canonical, atol=1e-6)
    assert np.linalg.norm(skeleton.offsets[18]) == pytest.approx(
        np.linalg.norm(joints[18] - joints[16]), rel=1e-6
    )


@pytest.mark.parametrize(
    "a, b",
    [
        ((1, 0, 0), (0, 1, 0)),
        ((0, 0, 1), (0, 0, 1)),
        ((1, 0, 0), (-1, 0, 0)),
        ((0.3, -0.8, 0.2), (0.9, 0.1, -0.4)),
    ],
)
def test_shortest_arc_is_a_rotation_taking_a_to_b(a, b):
    r = shortest_arc(np.array(a, float), np.array(b, float))
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-9) and np.linalg.det(r) == pytest.approx(1.0)
    assert np.allclose(r @ (np.array(a) / np.linalg.norm(a)), np.array(b) / np.linalg.norm(b), atol=1e-9)


def test_bad_meshes_and_shapes_are_refused():
    with pytest.raises(ValueError, match="finite vertices"):
        fit_body(np.full((100, 3), np.nan), rest_joint_positions())
    with pytest.raises(ValueError, match="22, 3"):
        fit_body(np.zeros((100, 3)), np.zeros((21, 3)))
    for bad in (
        {"height": 1.5},
        {"weight": -0.1},
        {"gender": "female"},
        {"age": float("nan")},
        {"muscle": True},
    ):
        with pytest.raises(ValueError, match="must be a number in"):
            BodyShape(**bad)
    assert BodyShape(height=np.float32(0.25)).vector.tolist() == [0.5, 0.5, 0.5, 0.5, 0.25, 0.5]


def test_body_json_round_trips_and_refuses_bad_fields(tmp_path):
    from hrr_garment.body.body_file import BodyRecord

    joints = rest_joint_positions()
    fitted = fit_body(_surface(DEFAULT_BODY, joints), joints)
    record = BodyRecord(
        fitted.skeleton, fitted.body, fitted.pelvis_height, fitted.stature, report=fitted.report
    )
    path = write_body(tmp_path / "body.json", record)
    back = read_body(path)
    assert np.allclose(back.skeleton.offsets, fitted.skeleton.offsets, atol=1e-6)
    assert [c.name for c in back.body.capsules] == [c.name for c in fitted.body.capsules]
    assert np.allclose(back.body.radii, fitted.body.radii) and back.pelvis_height == pytest.approx(
        fitted.pelvis_height
    )
    data = json.loads(path.read_text())
    for edit, message in (
        (lambda d: d.update(format_version=3), "format_version 3"),  # newer than this reads
        (lambda d: d.update(joints=d["joints"][::-1]), "canonical joints"),
        (lambda d: d["offsets"][3].__setitem__(1, 9.0), "offset of spine1"),
        (lambda d: d["capsules"][0].update(radius=-0.1), "capsule hips radius"),
        (lambda d: d["capsules"][0].update(joint="tail"), "canonical joints"),
        (lambda d: d.update(pelvis_height="tall"), "pelvis_height"),
        (lambda d: d.pop("stature"), "stature"),
    ):
        bad = json.loads(json.dumps(data))
        edit(bad)
        (tmp_path / "bad.json").write_text(json.dumps(bad))
        with pytest.raises(InputError, match=message):
            read_body(tmp_path / "bad.json")
    (tmp_path / "text.json").write_text("not json")
    with pytest.raises(InputError, match="not a body file"):
        read_body(tmp_path / "text.json")
    assert replace(record, shape={"height": 0.5}).shape == {"height": 0.5}


def test_a_uniformly_larger_body_plays_the_clip_exactly_that_much_larger():
    from hrr_garment.body.retarget import motion_on_body
    from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT
    from hrr_garment.motion.synth import synthesize

    motion = synthesize("walk", 1.0, seed=2)
    larger = _BodyLike(Skeleton(offsets=(REST_OFFSETS * 1.12).astype(np.float32)), REST_PELVIS_HEIGHT * 1.12)
    played = motion_on_body(motion, larger)
    assert np.allclose(played.joint_positions, 1.12 * motion.joint_positions, atol=1e-5)
    assert np.array_equal(played.local_rotations, motion.local_rotations)
    same = motion_on_body(motion, _BodyLike(Skeleton(), REST_PELVIS_HEIGHT))
    assert np.allclose(same.joint_positions, motion.joint_positions, atol=1e-9)


class _BodyLike:
    """The two things motion_on_body reads of a body."""

    def __init__(self, skeleton, pelvis_height):
        self.skeleton, self.pelvis_height = skeleton, pelvis_height
