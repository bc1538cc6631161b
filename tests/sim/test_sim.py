"""Cloth simulation (newton VBD on Warp's CPU device): every garment survives a walk and a spin,
explosions are caught, the lead-in starts from the rest pose."""

import numpy as np
import pytest

from hrr_garment.garment.templates import GARMENT_NAMES, make_garment
from hrr_garment.motion.frame import to_body_frame
from hrr_garment.motion.rotations import yaw_of
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.lead_in import with_lead_in
from hrr_garment.sim.quality import sequence_stats


def test_lead_in_starts_in_rest_pose_where_the_clip_starts():
    clip = synthesize("walk_curve", 1.0, seed=3)
    from hrr_garment.sim.simulator import SimSettings

    ext, lead = with_lead_in(clip, SimSettings.settle_s, SimSettings.blend_s)
    assert lead == 39 and ext.num_frames == clip.num_frames + 39
    assert np.array_equal(ext.local_rotations[lead:], clip.local_rotations)
    # Rest pose (only the root turned) at the clip's start position and heading.
    assert np.allclose(ext.local_rotations[0, 1:], np.eye(3), atol=1e-6)
    assert np.allclose(ext.root_translation[0, [0, 2]], clip.root_translation[0, [0, 2]])
    assert np.isclose(yaw_of(ext.global_rotations[0, 0]), yaw_of(clip.global_rotations[0, 0]), atol=1e-5)
    # The blend is gentle: joints move under 2.4 m/s (arms coming down), slower than the clip's feet.
    step = np.linalg.norm(np.diff(ext.joint_positions, axis=0), axis=-1).max(1)
    assert step[:lead].max() < 0.08 and step[: lead + 1].max() <= step[lead:].max()


def test_ground_level_body_frame_removes_root_motion():
    clip = synthesize("walk_curve", 2.0, seed=1)
    pelvis = clip.joint_positions[:, :1]
    local = to_body_frame(pelvis, clip, ground=True)
    assert np.allclose(local[..., [0, 2]], 0.0, atol=1e-9)
    assert np.allclose(local[..., 1], pelvis[..., 1])


@pytest.fixture(scope="module")
def simulator():
    pytest.importorskip("newton", reason="the sim extra is not installed")
    from hrr_garment.sim.simulator import SimSettings, simulate_garment

    return simulate_garment, SimSettings


@pytest.mark.sim
@pytest.mark.parametrize("name", GARMENT_NAMES)
def test_every_garment_survives_walk_and_spin(simulator, name):
    simulate_garment, SimSettings = simulator
    garment = make_garment(name, 300)
    for kind in ("walk", "spin"):
        clip = synthesize(kind, 2.0, seed=0)
        result = simulate_garment(garment, clip, SimSettings())
        assert result.vertices.shape == (clip.num_frames, garment.num_vertices, 3)
        assert result.attempts == 1, f"{name} {kind} needed a retry"
        stats = sequence_stats(
            result.vertices, garment.vertices, garment.edges(), clip, garment.groups["hem"]
        )
        assert stats["finite"]
        assert stats["strain_p99"] < 1.15, stats
        assert stats["penetration_max"] < 0.03, stats  # coarse tiny meshes; the quick dataset is held to 1 %
        assert stats["hem_swing_m"] > 0.02, stats  # it swings; rigid skinning would give ~0
        # Attached vertices ride on the body: the waistband stays within a few cm of its skinned place.
        from hrr_garment.garment.attachment import bind_attached

        pinned = bind_attached(garment).pose(clip.global_rotations.astype(np.float64), clip.joint_positions)
        assert np.abs(result.vertices[:, garment.attached] - pinned).max() < 0.05


@pytest.mark.sim
def test_explosion_is_detected_retried_and_reported(simulator):
    simulate_garment, SimSettings = simulator
    from hrr_garment.sim.simulator import SimulationExploded

    garment = make_garment("skirt", 200)
    clip = synthesize("walk", 0.5, seed=0)
    with pytest.raises(SimulationExploded) as info:
        simulate_garment(
            garment, clip, SimSettings(max_strain=1.0 + 1e-4, retries=1, settle_s=0.1, blend_s=0.1)
        )
    message = str(info.value)
    assert "edge strain" in message and "(10 substeps)" in message and "(20 substeps)" in message
    assert "(40 substeps)" in message  # the last doubling, once every attempt has failed


@pytest.mark.sim
def test_a_spin_too_fast_for_the_substeps_holds_at_one_more_doubling(simulator):
    """A pirouette at 4 turns a second tears the cloth at the schedule's substeps (an edge past the
    gate); rather than dropping the clip, the simulator doubles the substeps once more and keeps it."""
    simulate_garment, SimSettings = simulator
    garment = make_garment("dress", 300)
    clip = synthesize("spin", 1.5, seed=1, revolutions_per_s=4.0, arm_raise=1.3)
    result = simulate_garment(
        garment, clip, SimSettings(substeps=8, iterations=1, retries=0, settle_s=0.1, blend_s=0.3)
    )
    assert (result.attempts, result.substeps) == (2, 16)
    assert np.isfinite(result.vertices).all() and len(result.vertices) == clip.num_frames


def _arms_in_the_hips(frames: int = 15, away: int = 0):
    """A still pose with both forearms deep in the hips (a capture flaw the simulator must survive),
    after ``away`` frames of the T-pose."""
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.rotations import axis_angle_to_matrix
    from hrr_garment.motion.skeleton import JOINT_INDEX, REST_PELVIS_HEIGHT

    local = np.broadcast_to(np.eye(3, dtype=np.float32), (frames, 22, 3, 3)).copy()
    for side, sign in (("l", 1.0), ("r", -1.0)):
        local[:, JOINT_INDEX[f"{side}_shoulder"]] = axis_angle_to_matrix(
            np.array([0.0, 0.0, np.radians(-115.0) * sign])
        )
        local[:away, JOINT_INDEX[f"{side}_shoulder"]] = np.eye(3, dtype=np.float32)  # the T-pose
    return Motion(local, np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (frames, 1)))


@pytest.mark.sim
def test_limbs_through_the_body_get_last_tries_with_the_arms_off_the_cloth(simulator):
    simulate_garment, SimSettings = simulator
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.body.self_contact import self_intersecting_frames
    from hrr_garment.sim.capsule_poses import ARMS_OFF_CAPSULES, capsule_transforms
    from hrr_garment.sim.scene import ClothScene
    from hrr_garment.sim.simulator import SimulationExploded

    garment = make_garment("skirt", 200)
    motion = _arms_in_the_hips()
    assert self_intersecting_frames(motion).all()
    # switching the arms off the cloth clears their particle-collision flag, and only theirs; on
    # again restores it
    _, _, half = capsule_transforms(motion, DEFAULT_BODY)
    scene = ClothScene(garment, garment.vertices, half, DEFAULT_BODY, SimSettings())
    before = scene.model.shape_flags.numpy().copy()
    scene.set_arm_contact(False)
    flags = scene.model.shape_flags.numpy()
    arms = [
        i
        for i, c in enumerate(DEFAULT_BODY.capsules)
        if c.name.endswith(tuple(f"_{p}" for p in ARMS_OFF_CAPSULES))
    ]
    touches_cloth = (flags[: len(DEFAULT_BODY.capsules)] & 4) > 0  # newton.ShapeFlags.COLLIDE_PARTICLES
    assert (
        len(arms) == 6
        and not touches_cloth[arms].any()
        and touches_cloth[np.setdiff1d(np.arange(len(flags) - 1), arms)].all()
    )
    scene.set_arm_contact(True)
    assert np.array_equal(scene.model.shape_flags.numpy(), before)
    # every attempt fails here (an impossible strain bound); the arms stay in the hips on every
    # frame, so the episode is the whole clip and the last attempt has the arms off throughout
    with pytest.raises(SimulationExploded) as info:
        simulate_garment(
            garment, motion, SimSettings(max_strain=1.0 + 1e-4, retries=1, settle_s=0.1, blend_s=0.1)
        )
    assert str(info.value).count("substeps") == 4 and "(10 substeps, arms off the cloth)" in str(info.value)
    assert str(info.value).endswith(
        "(40 substeps, arms off the cloth)"
    )  # then one more doubling, arms as they were
    # arms that reach the hips part-way through: first off during that episode only, then throughout
    late = _arms_in_the_hips(15, away=8)
    assert not self_intersecting_frames(late)[:8].any() and self_intersecting_frames(late)[8:].all()
    with pytest.raises(SimulationExploded) as info:
        simulate_garment(
            garment, late, SimSettings(max_strain=1.0 + 1e-4, retries=1, settle_s=0.1, blend_s=0.1)
        )
    reasons = str(info.value).split("; ")
    assert len(reasons) == 6 and all(
        "(10 substeps, arms off the cloth on 7 frames)" in r for r in reasons[2:4]
    )
    assert reasons[4].endswith("(10 substeps, arms off the cloth)") and reasons[5].endswith(
        "(40 substeps, arms off the cloth)"
    )
    result = simulate_garment(garment, motion, SimSettings(settle_s=0.1, blend_s=0.1))
    assert (
        result.arms_off_frames == 0 and result.attempts == 1
    )  # a motion that holds keeps its arms on the cloth
