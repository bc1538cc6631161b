import numpy as np
import torch

from hrr_garment.motion.rotations import axis_angle_to_matrix
from hrr_garment.motion.skeleton import (
    CANONICAL,
    JOINT_NAMES,
    PARENTS,
    REST_PELVIS_HEIGHT,
    forward_kinematics,
    global_to_local,
)


def test_rest_pose_is_a_1p7m_t_pose_standing_on_the_ground():
    from hrr_garment.motion.motion import Motion

    assert len(JOINT_NAMES) == 22 and JOINT_NAMES[0] == "pelvis" and JOINT_NAMES[21] == "r_wrist"
    rest = CANONICAL.rest_positions(root=[0.0, REST_PELVIS_HEIGHT, 0.0])
    assert abs(rest[JOINT_NAMES.index("head"), 1] + 0.14 - 1.70) < 1e-6
    assert rest[JOINT_NAMES.index("l_hip"), 0] > 0  # left is +x
    assert rest[JOINT_NAMES.index("l_foot"), 2] > rest[JOINT_NAMES.index("l_ankle"), 2]  # faces +z
    # arms horizontal (T-pose)
    assert abs(rest[JOINT_NAMES.index("l_wrist"), 1] - rest[JOINT_NAMES.index("l_shoulder"), 1]) < 1e-9
    m = Motion(np.tile(np.eye(3), (1, 22, 1, 1)), [[0.0, REST_PELVIS_HEIGHT, 0.0]])
    np.testing.assert_allclose(m.sole_heights(), 0.0, atol=1e-6)


def test_fk_batched_numpy_equals_torch_and_local_round_trip(rng):
    local = axis_angle_to_matrix(rng.normal(scale=0.5, size=(7, 22, 3)))
    root = rng.normal(size=(7, 3))
    g_np, p_np = forward_kinematics(local, root, CANONICAL.offsets.astype(np.float64), PARENTS)
    g_t, p_t = forward_kinematics(
        torch.from_numpy(local),
        torch.from_numpy(root),
        torch.from_numpy(CANONICAL.offsets.astype(np.float64)),
        PARENTS,
    )
    np.testing.assert_allclose(g_np, g_t.numpy(), atol=1e-12)
    np.testing.assert_allclose(p_np, p_t.numpy(), atol=1e-12)
    np.testing.assert_allclose(global_to_local(g_np, PARENTS), local, atol=1e-12)
    # bone lengths are preserved by any pose
    for j, p in enumerate(PARENTS[1:], start=1):
        np.testing.assert_allclose(
            np.linalg.norm(p_np[:, j] - p_np[:, p], axis=1), np.linalg.norm(CANONICAL.offsets[j]), rtol=1e-6
        )
