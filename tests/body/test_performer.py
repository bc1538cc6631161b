"""A performer's body: the rig's own limbs on anny's nearest shape (hrr_garment.body.performer)."""

import numpy as np
import pytest

from hrr_garment.body.performer import HAND_RADIUS_MAX, LIMB_BONES, performer_body, performer_skeleton
from hrr_garment.body.proportions import proportions
from hrr_garment.errors import InputError
from hrr_garment.motion.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS, REST_OFFSETS, Skeleton


def test_the_limbs_take_the_given_lengths_along_the_canonical_directions_and_the_hips_the_given_joints():
    joints = Skeleton().rest_positions()
    joints[JOINT_INDEX["l_hip"]] += [0.02, 0.01, 0.0]  # wider hips than the mannequin's directions give
    limbs = {"upper_leg": 0.45, "lower_leg": 0.43, "upper_arm": 0.29, "forearm": 0.21}
    skeleton = performer_skeleton(Skeleton(), joints, limbs)
    measured = proportions(skeleton.rest_positions())
    for name, length in limbs.items():
        assert measured[name] == pytest.approx(length, abs=1e-6), name
        end = JOINT_INDEX[f"r_{LIMB_BONES[name]}"]
        direction = skeleton.offsets[end] / np.linalg.norm(skeleton.offsets[end])
        assert direction == pytest.approx(REST_OFFSETS[end] / np.linalg.norm(REST_OFFSETS[end]), abs=1e-6)
    assert skeleton.offsets[JOINT_INDEX["l_hip"]] == pytest.approx([0.11, -0.07, 0.0], abs=1e-6)
    assert skeleton.offsets[JOINT_INDEX["spine3"]] == pytest.approx(
        REST_OFFSETS[JOINT_INDEX["spine3"]]
    )  # the torso as given


def _rig_file(tmp_path, offsets: np.ndarray):
    """A BVH in centimetres of a walk on a rig with ``offsets`` (22, 3) metres."""
    from hrr_garment.motion.bvh_write import BvhStyle, write_bvh
    from hrr_garment.motion.synth import synthesize

    motion = synthesize("walk", 1.0, seed=1)
    path = tmp_path / "rig.bvh"
    write_bvh(
        path,
        list(JOINT_NAMES),
        list(PARENTS),
        offsets * 100,
        motion.local_rotations.astype(np.float64),
        motion.root_translation * 100,
        1 / 30,
        BvhStyle(unit_scale=0.01),
    )
    return path


@pytest.mark.slow
def test_a_rig_made_from_an_anny_body_comes_back_with_its_bone_lengths(tmp_path):
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    from hrr_garment.body.parametric import BodyShape, parametric_body

    truth = parametric_body(BodyShape(height=0.7, weight=0.3, gender=0.9))
    path = _rig_file(tmp_path, truth.fitted.skeleton.offsets.astype(np.float64))
    found = performer_body(path)
    rig = proportions(truth.fitted.skeleton.rest_positions())
    body = proportions(found.body.skeleton.rest_positions())
    for name in LIMB_BONES:  # the rig's own limbs, to the millimetre
        assert body[name] == pytest.approx(rig[name], abs=1e-3), name
        assert abs(found.errors_mm[name]) < 1.0
    # its hips are anny's own joints: as wide as the body the rig was made from
    assert body["hip_width"] == pytest.approx(proportions(truth.mesh.joints)["hip_width"], abs=0.02)
    assert abs(found.shape["height"] - 0.7) < 0.1 and set(found.shape) == set(BodyShape().to_dict())
    assert abs(found.stature - truth.fitted.stature) < 0.03
    assert found.body.pelvis_height == pytest.approx(
        truth.mesh.joints[0, 1], abs=0.015
    )  # anny's pelvis joint
    assert max(c.radius for c in found.body.capsules if c.name.endswith("_hand")) <= HAND_RADIUS_MAX
    again = performer_body(path)  # the same file, the same body, bit for bit
    assert np.array_equal(again.body.skeleton.offsets, found.body.skeleton.offsets)
    assert (
        np.array_equal(again.body.radii, found.body.radii)
        and again.body.pelvis_height == found.body.pelvis_height
    )


@pytest.mark.slow
def test_a_cmu_performers_body_plays_its_clip(mocap_dir):
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    from hrr_garment.body.retarget import motion_on_body
    from hrr_garment.motion.io import load_motion

    path = mocap_dir / "cmu" / "02_01.bvh"
    found = performer_body(path)
    assert 1.5 < found.stature < 2.0 and np.isfinite(found.rms_mm)
    on_body = motion_on_body(load_motion(path), found.body)
    assert on_body.skeleton is found.body.skeleton and np.isfinite(on_body.joint_positions).all()


def test_a_file_without_a_rig_has_no_performers_body(tmp_path):
    with pytest.raises(InputError, match="npz files carry none"):
        performer_body(tmp_path / "clip.npz")
