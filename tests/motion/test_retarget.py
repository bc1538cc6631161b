"""Naming schemes and custom maps: the same movement gives the same canonical motion."""

import numpy as np
import pytest
import yaml

from hrr_garment import load_motion, motion_features, synthesize
from hrr_garment.motion.bvh_write import BvhStyle, write_bvh
from hrr_garment.motion.joint_maps import NAMING_SCHEMES
from hrr_garment.motion.skeleton import CANONICAL, JOINT_INDEX, JOINT_NAMES, PARENTS


def write_named(motion, path, names, **kw):
    write_bvh(
        path,
        names,
        list(PARENTS),
        CANONICAL.offsets,
        motion.local_rotations.astype(np.float64),
        motion.root_translation,
        1 / 30,
        BvhStyle(**kw),
    )


@pytest.mark.parametrize(
    "scheme,prefix", [("mixamo", "mixamorig:"), ("cmu", ""), ("cmu_max", ""), ("smpl", "")]
)
def test_naming_schemes_are_detected_and_exact(tmp_path, scheme, prefix):
    motion = synthesize("dance", 2.0, seed=1)
    names = [prefix + NAMING_SCHEMES[scheme][n][0] for n in JOINT_NAMES]
    path = tmp_path / f"{scheme}.bvh"
    write_named(motion, path, names, unit_scale=100.0 if scheme == "mixamo" else 1.0)
    loaded = load_motion(path)
    assert loaded.source_skeleton == scheme
    assert np.abs(motion_features(loaded) - motion_features(motion)).max() <= 1e-4


def test_bandai_namco_names_with_one_spine_joint_fewer(tmp_path):
    motion = synthesize("walk", 2.0, seed=2)
    # Build a Bandai-Namco-style skeleton: no spine2; Chest carries spine2 and spine3 combined.
    keep = [j for j in range(22) if JOINT_NAMES[j] != "spine2"]
    table = NAMING_SCHEMES["bandai_namco"]
    names = [table[JOINT_NAMES[j]][0] for j in keep]
    new_index = {j: i for i, j in enumerate(keep)}
    s2, s3 = JOINT_INDEX["spine2"], JOINT_INDEX["spine3"]
    parents = [
        new_index[s2 and PARENTS[s2]]
        if PARENTS[j] == s2
        else (new_index[PARENTS[j]] if PARENTS[j] >= 0 else -1)
        for j in keep
    ]
    offsets = CANONICAL.offsets[keep].astype(np.float64).copy()
    offsets[new_index[s3]] = CANONICAL.offsets[s2] + CANONICAL.offsets[s3]
    local = motion.local_rotations.astype(np.float64)[:, keep].copy()
    local[:, new_index[s3]] = motion.local_rotations[:, s2] @ motion.local_rotations[:, s3]
    path = tmp_path / "bandai.bvh"
    write_bvh(path, names, parents, offsets, local, motion.root_translation, 1 / 30)
    loaded = load_motion(path)
    assert loaded.source_skeleton == "bandai_namco"
    legs = [JOINT_INDEX[n] for n in ("pelvis", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle")]
    np.testing.assert_allclose(loaded.joint_positions[:, legs], motion.joint_positions[:, legs], atol=1e-4)
    arms = [JOINT_INDEX[n] for n in ("l_wrist", "r_wrist", "head")]
    assert np.abs(loaded.joint_positions[:, arms] - motion.joint_positions[:, arms]).max() < 0.03


def test_custom_joint_map_yaml(tmp_path):
    motion = synthesize("walk", 2.0, seed=3)
    names = [f"bone_{i:02d}" for i in range(22)]
    path = tmp_path / "custom.bvh"
    write_named(motion, path, names)
    joint_map = tmp_path / "map.yaml"
    joint_map.write_text(yaml.safe_dump({n: f"bone_{i:02d}" for i, n in enumerate(JOINT_NAMES)}))
    loaded = load_motion(path, joint_map=joint_map)
    assert loaded.source_skeleton == "custom"
    assert np.abs(motion_features(loaded) - motion_features(motion)).max() <= 1e-4
    bad_map = tmp_path / "bad.yaml"
    bad_map.write_text(yaml.safe_dump({"pelvis": "bone_00", "elbow_of_doom": "bone_01"}))
    from hrr_garment import SkeletonMappingError

    with pytest.raises(SkeletonMappingError, match="elbow_of_doom"):
        load_motion(path, joint_map=bad_map)


def test_arms_down_rest_pose_is_aligned(tmp_path):
    """A source whose rest pose has the arms hanging (like CMU 131_xx) drives the same arm directions."""
    motion = synthesize("walk", 2.0, seed=4)
    offsets = CANONICAL.offsets.astype(np.float64).copy()
    local = motion.local_rotations.astype(np.float64).copy()
    from hrr_garment.motion.rotations import axis_angle_to_matrix

    for side, sign in (("l", 1.0), ("r", -1.0)):
        down = axis_angle_to_matrix(np.array([0.0, 0.0, -sign * np.pi / 2]))  # rest arm along -y
        for joint in ("elbow", "wrist"):
            j = JOINT_INDEX[f"{side}_{joint}"]
            offsets[j] = down @ offsets[j]
        # Same world pose with the new rest: every arm joint's global rotation gains a "down^T".
        s, e, w = (JOINT_INDEX[f"{side}_{n}"] for n in ("shoulder", "elbow", "wrist"))
        local[:, s] = local[:, s] @ down.T
        local[:, e] = down @ local[:, e] @ down.T
        local[:, w] = down @ local[:, w] @ down.T
    path = tmp_path / "armsdown.bvh"
    write_bvh(path, list(JOINT_NAMES), list(PARENTS), offsets, local, motion.root_translation, 1 / 30)
    loaded = load_motion(path)
    np.testing.assert_allclose(loaded.joint_positions, motion.joint_positions, atol=1e-4)


def test_a_rig_without_a_standing_rest_pose_keeps_the_garment_attachment(tmp_path):
    """Rigs exported with their joint orientations baked in (Bandai-Namco's: every bone along +x in
    the zero pose) carry an arbitrary constant roll per joint. Retargeting must not pass it on: the
    dress's attached vertices (waistband and strap tops, skinned to the torso joints) land where
    they do on the original motion."""
    from hrr_garment.garment.attachment import bind_attached
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.motion.retarget import rest_is_standing
    from hrr_garment.motion.rotations import axis_angle_to_matrix
    from hrr_garment.motion.skeleton import rest_positions

    motion = synthesize("walk", 2.0, seed=5)
    roll = axis_angle_to_matrix(np.random.default_rng(0).normal(size=(22, 3)) * 1.5)  # per-joint rig frames
    g_true = motion.global_rotations
    local = np.empty_like(g_true)
    local[:, 0] = g_true[:, 0] @ roll[0]
    for j in range(1, 22):
        p = PARENTS[j]
        local[:, j] = roll[p].T @ motion.local_rotations[:, j].astype(np.float64) @ roll[j]
    offsets = np.stack(
        [roll[PARENTS[j]].T @ CANONICAL.offsets[j] if j else CANONICAL.offsets[j] for j in range(22)]
    )
    assert not rest_is_standing(rest_positions(offsets, PARENTS), {j: j for j in range(22)})
    path = tmp_path / "baked.bvh"
    write_bvh(path, list(JOINT_NAMES), list(PARENTS), offsets, local, motion.root_translation, 1 / 30)
    loaded = load_motion(path)
    np.testing.assert_allclose(loaded.joint_positions, motion.joint_positions, atol=1e-3)
    binding = bind_attached(make_garment("dress", 400))
    expected = binding.pose(motion.global_rotations, motion.joint_positions)
    got = binding.pose(loaded.global_rotations, loaded.joint_positions)
    assert np.linalg.norm(got - expected, axis=-1).max() < 0.01  # metres
