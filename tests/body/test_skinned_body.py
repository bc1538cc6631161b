"""The visible body: linear blend skinning gives the rest mesh back at the rest pose, moves rigidly
with a rigid motion, blends at a joint; anny's weights gathered onto the canonical joints."""

import numpy as np
import pytest

from hrr_garment.body.capsules import DEFAULT_BODY, body_mesh
from hrr_garment.body.skinned_body import SkinnedBody, rest_frames, skinned_body
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.rotations import axis_angle_to_matrix
from hrr_garment.motion.skeleton import JOINT_INDEX
from hrr_garment.motion.synth import synthesize


class _Rest:
    """The mannequin's capsule surface as a rest mesh, standing in its T-pose, with its joints."""

    def __init__(self):
        a, b = DEFAULT_BODY.rest_pose()
        self.vertices, self.faces = body_mesh(a, b, DEFAULT_BODY.radii, 12, 6)
        self.joints = DEFAULT_BODY.rest_joints()


def _mannequin(seed: int = 0) -> SkinnedBody:
    """The mannequin skinned to random weights on each vertex's two nearest joints."""
    rest = _Rest()
    d = np.linalg.norm(rest.vertices[:, None] - rest.joints[None], axis=-1)
    nearest = np.argsort(d, 1)[:, :2]
    share = np.random.default_rng(seed).random(len(d))
    weights = np.zeros_like(d)
    np.put_along_axis(weights, nearest, np.stack([share, 1.0 - share], 1), 1)
    return skinned_body(DEFAULT_BODY.skeleton, rest, weights)


def test_at_the_rest_pose_it_is_the_rest_mesh():
    body = _mannequin()
    posed = body.pose(body.rest_rotations[None], body.rest_positions[None])
    assert np.abs(posed[0] - body.vertices).max() < 1e-9
    # the rest frames are those of a motion of the skeleton standing in the mesh's pose (a T-pose)
    rest = Motion(
        np.broadcast_to(np.eye(3, dtype=np.float32), (1, 22, 3, 3)).copy(), body.rest_positions[None, 0]
    )
    assert np.abs(body.pose(rest.global_rotations, rest.joint_positions)[0] - body.vertices).max() < 1e-6
    rot, pos = rest_frames(DEFAULT_BODY.skeleton, _Rest().joints)
    assert np.allclose(rot, np.eye(3), atol=1e-6) and np.allclose(pos, _Rest().joints, atol=1e-5)


def test_a_rigid_motion_moves_it_rigidly_and_a_joint_blends():
    body = _mannequin()
    walk = synthesize("walk", 0.3, seed=1)
    rot, pos = walk.global_rotations, walk.joint_positions
    turn = axis_angle_to_matrix(np.array([0.3, -1.1, 0.4]))
    shift = np.array([0.5, -0.2, 1.5])
    moved = body.pose(turn @ rot, pos @ turn.T + shift)
    assert np.abs(moved - (body.pose(rot, pos) @ turn.T + shift)).max() < 1e-9
    # a vertex weighted half to each of two joints lies halfway between where each would carry it
    rigid = [
        SkinnedBody(
            body.vertices,
            body.faces,
            np.eye(22)[np.full(len(body.vertices), j)],
            body.rest_rotations,
            body.rest_positions,
        )
        for j in (JOINT_INDEX["l_elbow"], JOINT_INDEX["l_wrist"])
    ]
    half = np.zeros_like(body.weights)
    half[:, [JOINT_INDEX["l_elbow"], JOINT_INDEX["l_wrist"]]] = 0.5
    blended = SkinnedBody(body.vertices, body.faces, half, body.rest_rotations, body.rest_positions)
    expected = 0.5 * (rigid[0].pose(rot, pos) + rigid[1].pose(rot, pos))
    assert np.abs(blended.pose(rot, pos) - expected).max() < 1e-9


def test_weights_that_do_not_sum_to_one_are_refused():
    body = _mannequin()
    with pytest.raises(ValueError, match="sum to 1"):
        SkinnedBody(body.vertices, body.faces, body.weights * 2, body.rest_rotations, body.rest_positions)


@pytest.mark.slow
def test_anny_weights_on_the_canonical_joints():
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    from hrr_garment.body.body_file import record_of
    from hrr_garment.body.parametric import BodyShape, parametric_body
    from hrr_garment.body.skinned_body import anny_weights, visible_body

    weights = anny_weights()
    assert weights.shape[1] == 22 and np.allclose(weights.sum(1), 1.0, atol=1e-5)
    record = record_of(parametric_body(BodyShape()))
    visible = visible_body(record)
    # the hands (anny's fingers) ride with the wrists, the head's top with the head
    top = np.argmax(visible.vertices[:, 1])
    assert weights[top, JOINT_INDEX["head"]] > 0.9
    lowest = np.argmin(visible.vertices[:, 0])  # the right hand's far end (anny's right is -x)
    assert weights[lowest, JOINT_INDEX["r_wrist"]] > 0.9
    assert (
        np.abs(
            visible.pose(visible.rest_rotations[None], visible.rest_positions[None])[0] - visible.vertices
        ).max()
        < 1e-9
    )
