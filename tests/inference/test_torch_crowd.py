"""The crowd as one torch step (a GPU's path), run on the CPU: each character as the native crowd
gives it, with either decoder; state per key; what it refuses."""

import numpy as np
import pytest

from hrr_garment.motion.poses import motion_to_poses
from hrr_garment.motion.synth import synthesize


@pytest.mark.parametrize("decoder", ["full", "fast"])
def test_the_device_crowd_equals_the_native_crowd(animator, decoder):
    clips = [synthesize("walk_curve", 1.0, seed=1), synthesize("spin", 1.0, seed=2)]
    poses = [motion_to_poses(c) for c in clips]
    native = animator.crowd(mode="regression", decoder=decoder, device="native")
    device = animator.crowd(mode="regression", decoder=decoder, device="cpu")
    worst = 0.0
    for t in range(16):
        keys = ["a", "b"] if t >= 5 else ["a"]  # b joins at frame 5
        rotations = np.stack([poses[i][0][t - (5 if k == "b" else 0)] for i, k in enumerate(keys)])
        roots = np.stack([poses[i][1][t - (5 if k == "b" else 0)] + [2.0 * i, 0, 0] for i, k in enumerate(keys)])
        ours, theirs = device.push(rotations, roots, keys), native.push(rotations, roots, keys)
        assert ours.shape == theirs.shape == (len(keys), animator.bundle.template.num_vertices, 3)
        worst = max(worst, float(np.abs(ours - theirs).max()))
    assert worst < 1e-4, f"{worst * 1000:.3f} mm from the native crowd"
    device.leave("a")
    assert device.characters == ["b"]
    with pytest.raises(KeyError, match="no character 'a'"):
        device.leave("a")


def test_a_device_crowd_runs_the_regression_only(animator):
    with pytest.raises(ValueError, match="regression"):
        animator.crowd(mode="hybrid", device="cpu")
    crowd = animator.crowd(mode="regression", device="cpu")
    rotations, roots = motion_to_poses(synthesize("walk", 0.2, seed=0))
    from hrr_garment.errors import InputError

    with pytest.raises(InputError, match="quaternions"):
        crowd.push(rotations[:2, :5], roots[:2])
    with pytest.raises(InputError, match="distinct"):
        crowd.push(rotations[:2], roots[:2], ["x", "x"])
