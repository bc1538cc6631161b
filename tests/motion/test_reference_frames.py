"""A conversion's leading T-pose (CMU's MotionBuilder-friendly BVH files) is dropped on reading;
motion that merely moves fast, or a fast step later in the clip, is kept."""

import numpy as np

from hrr_garment.motion.bvh_write import write_bvh
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.reference_frames import leading_reference_frames
from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS
from hrr_garment.motion.synth import synthesize

FPS = 120.0


def _clip() -> Motion:
    walk = synthesize("walk", 4.0, seed=4)  # played at 120 fps: a brisk but human motion
    return Motion(walk.local_rotations, walk.root_translation, FPS)


def _with_lead(motion: Motion, frames: int, shift_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The motion after ``frames`` T-pose frames, those ``shift_m`` away along x."""
    rot = np.concatenate(
        [np.broadcast_to(np.eye(3), (frames, *motion.local_rotations.shape[1:])), motion.local_rotations]
    )
    lead_root = np.repeat(motion.root_translation[:1] + [shift_m, 0.0, 0.0], frames, 0)
    return rot, np.concatenate([lead_root, motion.root_translation])


def test_a_leading_t_pose_is_found_and_motion_is_not(monkeypatch):
    motion = _clip()
    assert leading_reference_frames(motion.local_rotations, motion.root_translation, FPS) == 0
    rot, root = _with_lead(motion, 1)
    assert leading_reference_frames(rot, root, FPS) == 1
    rot, root = _with_lead(motion, 5, shift_m=2.0)  # several, at another place: the root's jump is the cut
    assert leading_reference_frames(rot, root, FPS) == 5
    late = motion.local_rotations.copy()
    late[60:, 1] = late[60:, 1] @ np.array(
        [[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]
    )  # a hip snaps 90 degrees, 0.5 s in
    assert leading_reference_frames(late, motion.root_translation, FPS) == 0
    monkeypatch.setattr("hrr_garment.motion.reference_frames.LEAD_S", 1.0)  # it is a cut, if early enough
    assert leading_reference_frames(late, motion.root_translation, FPS) == 60


def test_a_bvh_with_a_leading_t_pose_reads_as_its_motion(tmp_path):
    motion = _clip()
    rot, root = _with_lead(motion, 1)
    paths = tmp_path / "lead.bvh", tmp_path / "plain.bvh"
    for path, (r, t) in zip(paths, [(rot, root), (motion.local_rotations, motion.root_translation)]):
        write_bvh(
            path,
            list(JOINT_NAMES),
            list(PARENTS),
            CANONICAL.offsets,
            r.astype(np.float64),
            t.astype(np.float64),
            1 / FPS,
        )
    with_lead, plain = load_motion(paths[0]), load_motion(paths[1])
    assert with_lead.num_frames == plain.num_frames
    np.testing.assert_allclose(with_lead.joint_positions, plain.joint_positions, atol=1e-5)
