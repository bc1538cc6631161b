import numpy as np
import pytest
import trimesh

from hrr_garment import synthesize
from hrr_garment.body import DEFAULT_BODY, body_mesh, capsule_signed_distance


def test_signed_distance_known_answers():
    a = np.array([[0.0, 0.0, 0.0]])
    b = np.array([[0.0, 1.0, 0.0]])
    r = np.array([0.1])
    pts = np.array([[0.0, 0.5, 0.0], [0.3, 0.5, 0.0], [0.0, 1.5, 0.0], [0.0, -0.2, 0.0], [0.05, 0.2, 0.0]])
    d, n, idx = capsule_signed_distance(pts, a, b, r)
    np.testing.assert_allclose(d, [-0.1, 0.2, 0.4, 0.1, -0.05], atol=1e-12)
    np.testing.assert_allclose(n[1], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(n[2], [0.0, 1.0, 0.0], atol=1e-12)
    assert (idx == 0).all()


def test_union_takes_the_nearest_capsule(rng):
    a = rng.normal(size=(4, 3))
    b = a + rng.normal(size=(4, 3))
    r = rng.uniform(0.05, 0.2, size=4)
    pts = rng.normal(size=(200, 3))
    d, _, idx = capsule_signed_distance(pts, a, b, r)
    singles = np.stack(
        [capsule_signed_distance(pts, a[i : i + 1], b[i : i + 1], r[i : i + 1])[0] for i in range(4)], 1
    )
    np.testing.assert_allclose(d, singles.min(1), atol=1e-12)
    np.testing.assert_array_equal(idx, singles.argmin(1))


def test_posed_body_mesh_lies_on_the_signed_distance_surface():
    motion = synthesize("dance", 1.0, seed=0)
    a, b = DEFAULT_BODY.pose_motion(motion)
    assert a.shape == (motion.num_frames, len(DEFAULT_BODY.capsules), 3)
    verts, faces = body_mesh(a[10], b[10], DEFAULT_BODY.radii)
    d, _, _ = capsule_signed_distance(verts, a[10], b[10], DEFAULT_BODY.radii)
    assert d.max() <= 1e-9 and np.abs(d).min() < 1e-9  # on or inside the union, never outside
    mesh = trimesh.Trimesh(verts, faces, process=False)
    assert len(mesh.faces) == len(faces) and mesh.area > 1.0  # an adult body is well over 1 m^2
    # Joints are inside the body; a point a metre in front of the pelvis is outside.
    joints = motion.joint_positions[10]
    d_j, _, _ = capsule_signed_distance(joints, a[10], b[10], DEFAULT_BODY.radii)
    assert (d_j < 0).all()
    d_far, _, _ = capsule_signed_distance(joints[:1] + [0.0, 0.0, 1.0], a[10], b[10], DEFAULT_BODY.radii)
    assert d_far[0] > 0.5


def test_body_dimensions_are_plausible():
    motion = synthesize("idle", 1.0, seed=0)
    a, b = DEFAULT_BODY.pose_motion(motion)
    verts, _ = body_mesh(a[0], b[0], DEFAULT_BODY.radii)
    height = verts[:, 1].max() - min(verts[:, 1].min(), 0.0)
    assert 1.6 < height < 1.8
    hips = [c.name for c in DEFAULT_BODY.capsules].index("hips")
    hip_verts, _ = body_mesh(
        a[0, hips : hips + 1], b[0, hips : hips + 1], DEFAULT_BODY.radii[hips : hips + 1]
    )
    width = np.ptp(hip_verts @ motion.global_rotations[0, 0][:, 0])  # along the pelvis' left-right axis
    assert 0.3 < width < 0.5  # hip width of an adult
    fuller = DEFAULT_BODY.scaled(1.2)
    assert fuller.radii == pytest.approx(1.2 * DEFAULT_BODY.radii)


def _arm_hanging(adduction_deg):
    """Both arms hanging and turned ``adduction_deg`` towards the body's midline: a still pose of
    10 frames for a number, one frame per angle for a sequence."""
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.rotations import axis_angle_to_matrix
    from hrr_garment.motion.skeleton import JOINT_INDEX, REST_PELVIS_HEIGHT

    angles = np.broadcast_to(
        np.asarray(adduction_deg, float), (10,) if np.ndim(adduction_deg) == 0 else np.shape(adduction_deg)
    )
    local = np.broadcast_to(np.eye(3, dtype=np.float32), (len(angles), 22, 3, 3)).copy()
    for side, sign in (("l", 1.0), ("r", -1.0)):
        angle = np.radians(-90.0 - angles) * sign  # about +z: the left arm swings down and in
        axis_angle = np.stack([np.zeros_like(angle), np.zeros_like(angle), angle], -1)
        local[:, JOINT_INDEX[f"{side}_shoulder"]] = axis_angle_to_matrix(axis_angle)
    root = np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (len(angles), 1))
    return Motion(local, root)


def test_limbs_through_the_body_are_flagged_and_ordinary_motion_is_not():
    from hrr_garment.body.self_contact import (
        SELF_INTERSECTION_DEPTH,
        limb_intrusion,
        self_intersecting_frames,
    )
    from hrr_garment.motion.synth import KINDS, synthesize

    for kind in KINDS:
        assert not self_intersecting_frames(synthesize(kind, 2.0, seed=0)).any(), kind
    outward, inward = _arm_hanging(-20.0), _arm_hanging(25.0)
    assert limb_intrusion(outward).max() < 0.0  # a gap between the surfaces
    assert limb_intrusion(inward).min() > SELF_INTERSECTION_DEPTH  # forearm and hand deep in the hips
    assert self_intersecting_frames(inward).all()


def test_a_self_intersection_episode_is_flagged_whole_with_its_recovery():
    from hrr_garment.body.self_contact import (
        LEG_PARTS,
        LOWER_ARM,
        PINCH_GAP,
        SELF_INTERSECTION_DEPTH,
        limb_intrusion,
        self_intersecting_frames,
        self_intersection_episodes,
    )

    # without the upper arms: in this motion they lie along the chest throughout (their own
    # episodes are tested below)
    parts = LOWER_ARM + LEG_PARTS
    # arms swing in through the hips, about 0.9 cm a degree from -4 degrees on, and out again
    ramp = np.arange(-6.0, 6.0)
    motion = _arm_hanging(np.concatenate([np.full(5, -20.0), ramp, ramp[::-1], np.full(10, -20.0)]))
    intrusion = limb_intrusion(motion, parts=parts)
    flagged = self_intersecting_frames(motion, parts=parts)
    episode = np.flatnonzero(intrusion > -PINCH_GAP)
    start, stop = episode[0], episode[-1] + 1
    assert (np.diff(episode) == 1).all() and intrusion.max() > SELF_INTERSECTION_DEPTH
    # shallow frames at both ends of the episode count with it, and so does the recovery
    assert ((intrusion > -PINCH_GAP) & (intrusion < SELF_INTERSECTION_DEPTH)).sum() >= 2
    recovery = round(0.1 * motion.fps)
    assert np.array_equal(np.flatnonzero(flagged), np.arange(start, stop + recovery))
    assert self_intersection_episodes(motion, parts=parts) == [(start, stop + recovery)]
    # a wider gap (the simulator's arms-off window) starts the same episode earlier, ends it later
    ((wide_start, wide_stop),) = self_intersection_episodes(motion, gap=0.032, parts=parts)
    assert wide_start < start and wide_stop > stop + recovery
    assert not self_intersecting_frames(motion, recovery_s=0.0, parts=parts)[stop:].any()
    # an episode that never passes the depth flags nothing
    shallow = _arm_hanging(np.concatenate([np.full(5, -20.0), ramp[:5], ramp[:5][::-1], np.full(5, -20.0)]))
    assert 0 < limb_intrusion(shallow, parts=parts).max() < SELF_INTERSECTION_DEPTH
    assert not self_intersecting_frames(shallow, parts=parts).any()


def test_an_upper_arm_in_the_chest_is_its_own_episode():
    from hrr_garment.body.self_contact import (
        LOWER_ARM,
        SELF_INTERSECTION_DEPTH,
        limb_intrusions,
        self_intersecting_frames,
    )

    # the arms hang 2.7 cm clear of the chest; in the middle frames the upper arms press 5.5 cm in
    # (CMU 131_03's right upper arm sinks 3.7 cm into the chest)
    angles = np.concatenate([np.full(10, -40.0), np.full(6, 10.0), np.full(14, -40.0)])
    motion = _arm_hanging(angles)
    upper = limb_intrusions(motion, parts=("upper_arm",))
    assert upper.shape == (2, len(angles)) and upper.max() > SELF_INTERSECTION_DEPTH
    flagged = self_intersecting_frames(motion, parts=("upper_arm",))
    recovery = round(0.1 * motion.fps)
    assert np.array_equal(np.flatnonzero(flagged), np.arange(10, 16 + recovery))
    # with the forearms and hands, which are deep only in the middle: the episodes join, no more
    both = self_intersecting_frames(motion)
    assert (both == (flagged | self_intersecting_frames(motion, parts=LOWER_ARM))).all()
