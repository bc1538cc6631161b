"""The body's own mesh in rigid pieces: at rest it is the mesh, posed it moves with the bones,
and its pieces in the simulator's capsule frames put it back where it was."""

import numpy as np

from hrr_garment.body.capsules import DEFAULT_BODY, body_mesh
from hrr_garment.body.mesh_collider import body_mesh as rigid_body_mesh
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.rotations import quat_to_matrix
from hrr_garment.motion.synth import synthesize


def _mannequin_mesh():
    """The mannequin's capsule surface as a mesh, standing in its T-pose, with its joints."""
    a, b = DEFAULT_BODY.rest_pose()
    vertices, faces = body_mesh(a, b, DEFAULT_BODY.radii, 16, 8)
    return vertices, faces, DEFAULT_BODY.rest_joints()


def test_at_rest_the_pieces_are_the_mesh_and_posed_they_ride_with_the_bones():
    from hrr_garment.sim.scene import capsule_transforms

    vertices, faces, joints = _mannequin_mesh()
    mesh = rigid_body_mesh(DEFAULT_BODY, vertices, faces, joints)
    rest = Motion(np.broadcast_to(np.eye(3, dtype=np.float32), (1, 22, 3, 3)).copy(), joints[None, 0])
    assert np.abs(mesh.pose(rest.global_rotations, rest.joint_positions)[0] - vertices).max() < 1e-9
    # every piece, placed by its capsule's simulator transform, lies on the mesh; together they cover it
    centre, quat, _ = capsule_transforms(rest, DEFAULT_BODY)
    turn = quat_to_matrix(np.concatenate([quat[..., 3:], quat[..., :3]], -1))[0]
    pieces = mesh.pieces(DEFAULT_BODY)
    for c, local, piece_faces in pieces:
        world = centre[0, c] + local @ turn[c].T
        assert np.linalg.norm(world[:, None] - vertices[None], axis=-1).min(1).max() < 1e-6
    assert sum(len(f) for _, _, f in pieces) >= len(
        faces
    )  # every face in a piece; neighbours overlap by a ring
    # posed, each vertex keeps its distance from its own joint (it rides with one bone)
    walk = synthesize("walk", 0.5, seed=0)
    posed = mesh.pose(walk.global_rotations, walk.joint_positions)
    own = np.linalg.norm(posed - walk.joint_positions[:, mesh.joint], axis=-1)
    assert np.allclose(own, own[0], atol=1e-5)
