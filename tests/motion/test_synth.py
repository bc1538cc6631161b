"""The procedural motion library: deterministic, finite, smooth, feet on the ground without skating."""

import numpy as np
import pytest

from hrr_garment import MOTION_KINDS, HRRError, synthesize

SEEDS = range(20)
# Largest joint acceleration allowed (m/s^2, second differences at 30 fps): about 15 g, what feet
# reach at a running footfall; anything above means a jump in velocity.
MAX_JOINT_ACCELERATION = 150.0
GROUND_TOLERANCE = 0.03
KINDS = sorted(MOTION_KINDS)
PIVOTING = {"spin"}


def test_at_least_the_required_kinds():
    required = {
        "idle",
        "walk",
        "run",
        "walk_curve",
        "turn_in_place",
        "side_step",
        "walk_backward",
        "jump",
        "hop",
        "spin",
        "dance",
    }
    assert required <= set(MOTION_KINDS)


@pytest.mark.parametrize("kind", KINDS)
def test_kind_over_seeds(kind):
    seen = set()
    for seed in SEEDS:
        motion = synthesize(kind, seconds=3.0, seed=seed)
        pos = motion.joint_positions
        assert (
            motion.num_frames == 90 and np.isfinite(pos).all() and np.isfinite(motion.local_rotations).all()
        )
        acc = np.linalg.norm(np.diff(pos, 2, axis=0), axis=-1) * motion.fps**2
        assert acc.max() <= MAX_JOINT_ACCELERATION, f"{kind} seed {seed}: acceleration {acc.max():.0f} m/s^2"
        soles = motion.sole_heights()  # (T, 6): three points per foot
        lowest = soles.min(1)
        assert lowest.min() >= -GROUND_TOLERANCE, (
            f"{kind} seed {seed}: foot {-lowest.min():.3f} m below ground"
        )
        # Standing phases: a foot whose ankle is (nearly) still. Its sole must be on the ground.
        for side, cols, ankle in (("l", slice(0, 3), 7), ("r", slice(3, 6), 8)):
            speed = np.linalg.norm(np.diff(pos[:, ankle], axis=0), axis=1) * motion.fps
            slow = speed < 0.02
            # still for at least four consecutive frame steps (a swing apex is only momentarily still)
            run4 = np.convolve(slow.astype(int), np.ones(4, int), mode="valid") == 4
            still = np.zeros(len(pos), bool)
            for k in np.flatnonzero(run4):
                still[k : k + 5] = True
            if still.any():
                assert np.abs(soles[still, cols].min(1)).max() <= GROUND_TOLERANCE, (
                    f"{kind} seed {seed}: {side} foot stands off the ground"
                )
        # No skating: a sole point resting on the ground does not slide.
        sole_pos = motion.sole_points()  # (T, 6, 3)
        if kind in PIVOTING:  # a pivoting foot turns about its ankle, which must stay put
            sole_pos = np.repeat(pos[:, [7, 8]], 3, axis=1)
        resting = soles < 0.001
        both = resting[1:] & resting[:-1]
        slide = np.linalg.norm(np.diff(sole_pos[..., [0, 2]], axis=0), axis=-1)[both]
        assert slide.size == 0 or slide.max() < 0.005, (
            f"{kind} seed {seed}: a planted foot slides {slide.max():.3f} m in a frame"
        )
        seen.add(round(float(motion.local_rotations[-1].sum() + pos[-1, 0].sum()), 5))
    assert len(seen) > 1  # seeds give different clips


@pytest.mark.parametrize("kind", KINDS)
def test_deterministic_per_seed(kind):
    a, b = synthesize(kind, 2.0, seed=11), synthesize(kind, 2.0, seed=11)
    np.testing.assert_array_equal(a.local_rotations, b.local_rotations)
    np.testing.assert_array_equal(a.root_translation, b.root_translation)


def test_parameters_take_effect_and_are_checked():
    slow = synthesize("walk", 4.0, seed=0, speed=0.7)
    fast = synthesize("walk", 4.0, seed=0, speed=1.6)
    assert slow.summary()["root_displacement_m"] == pytest.approx(0.7 * 4.0, rel=0.1)
    assert fast.summary()["root_displacement_m"] == pytest.approx(1.6 * 4.0, rel=0.1)
    with pytest.raises(HRRError, match="no parameter"):
        synthesize("walk", 2.0, seed=0, sped=1.0)
    with pytest.raises(HRRError, match="unknown motion kind"):
        synthesize("moonwalk", 2.0)


def test_jump_leaves_the_ground_and_spin_turns():
    jump = synthesize("jump", 4.0, seed=3, height=0.25)
    assert jump.lowest_foot_height().max() > 0.15
    spin = synthesize("spin", 4.0, seed=3, revolutions_per_s=1.0)
    from hrr_garment.motion.frame import body_heading

    turns = abs(np.unwrap(body_heading(spin)[0])[-1] - body_heading(spin)[0][0]) / (2 * np.pi)
    assert turns > 2.0


@pytest.mark.parametrize("kind", KINDS)
def test_legs_do_not_pass_through_each_other(kind):
    """Turning, side-stepping and pivoting once swung a knee or foot 6-11 cm into the other leg,
    trapping the skirt between two capsules; the engine now keeps the legs apart."""
    from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance

    names = [c.name for c in DEFAULT_BODY.capsules]
    left = [names.index(n) for n in ("l_thigh", "l_shin")]
    right = [names.index(n) for n in ("r_thigh", "r_shin")]
    radii = DEFAULT_BODY.radii
    for seed in range(4):
        motion = synthesize(kind, 3.0, seed=seed)
        a, b = DEFAULT_BODY.pose_motion(motion)
        s = np.linspace(0, 1, 9)[:, None]
        for t in range(0, motion.num_frames, 2):
            for i in left:
                points = a[t, i] + s * (b[t, i] - a[t, i])
                gap = capsule_signed_distance(points, a[t, right], b[t, right], radii[right])[0] - radii[i]
                assert gap.min() > -0.005, (
                    f"{kind} seed {seed} frame {t}: {names[i]} {-gap.min():.3f} m inside the right leg"
                )
