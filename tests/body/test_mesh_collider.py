"""The body the viewer sees as the simulator's collider: its skinned mesh cut into pieces by capsule,
each face in exactly one piece, and the pieces, placed by their capsules' simulator transforms,
are the skinned mesh in every pose."""

import numpy as np

from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.body.mesh_collider import skinned_pieces
from hrr_garment.motion.rotations import quat_to_matrix
from hrr_garment.motion.synth import synthesize

from .test_skinned_body import _mannequin


def test_the_pieces_partition_the_mesh_and_placed_by_their_capsules_are_the_skinned_mesh():
    from hrr_garment.sim.capsule_poses import capsule_transforms

    skin = _mannequin()
    collider = skinned_pieces(DEFAULT_BODY, skin)
    # every face in exactly one piece, and on the capsule it lies along (near it at rest)
    faces = np.concatenate([p.vertices[p.faces] for p in collider.pieces])
    assert len(faces) == len(skin.faces)
    assert {tuple(sorted(f)) for f in faces} == {tuple(sorted(f)) for f in skin.faces}
    assert len({p.capsule for p in collider.pieces}) == len(collider.pieces) > 10
    walk = synthesize("walk", 0.5, seed=0)
    centre, quat, _ = capsule_transforms(walk, DEFAULT_BODY)
    local = collider.local_frames(walk, centre, quat)
    turn = quat_to_matrix(np.concatenate([quat[..., 3:], quat[..., :3]], -1))
    posed = skin.pose(walk.global_rotations, walk.joint_positions)
    rows = collider.offsets
    assert rows[-1] == local.shape[1]
    for i, piece in enumerate(collider.pieces):
        world = centre[:, piece.capsule, None] + np.einsum(
            "tij,tvj->tvi", turn[:, piece.capsule], local[:, rows[i] : rows[i + 1]]
        )
        assert np.abs(world - posed[:, piece.vertices]).max() < 1e-5
