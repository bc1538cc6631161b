"""A procedural clip's carriage (motion/synth/posture.py): drawn per seed about the real clips'
(the pelvis pitched forward, the chest leaning back from it, the collars turned), added to the
kind's own motion without changing its steps; the upright posture is the kind's body; a procedural
sequence's key says which clips it was simulated from."""

import numpy as np
import pytest

from hrr_garment.motion.skeleton import JOINT_INDEX as J
from hrr_garment.motion.synth import UPRIGHT, Posture, synthesize
from hrr_garment.motion.synth.posture import DEG, carriage
from hrr_garment.sim.plan import SequenceSpec


def _carriage(motion) -> tuple[float, float, float]:
    measured = carriage(motion)
    return measured.pelvis_pitch, measured.chest_lean, measured.collar


def test_drawn_postures_are_held_as_real_performers_hold_them():
    """Over 30 walks the pelvis pitches forward and the chest leans back from it, about the real
    clips' 10 deg each, and the collars turn; upright, the kind's walk has neither."""
    drawn = np.array([_carriage(synthesize("walk", 2.0, seed=s)) for s in range(30)])
    upright = np.array([_carriage(synthesize("walk", 2.0, seed=s, posture=UPRIGHT)) for s in range(30)])
    assert 6.0 < drawn[:, 0].mean() - upright[:, 0].mean() < 12.0
    assert -14.0 < drawn[:, 1].mean() - upright[:, 1].mean() < -6.0
    assert drawn[:, 0].std() > 3.0 and drawn[:, 1].std() > 3.0  # a spread of carriages, not one
    assert upright[:, 2].max() < 1e-3 and 6.0 < drawn[:, 2].mean() < 16.0


@pytest.mark.parametrize("kind", ["walk", "dance", "jump"])
def test_a_posture_keeps_the_kinds_steps(kind):
    """The posture is drawn after the kind's own draws: the same seed's ground path and feet, only
    the body above them carried otherwise."""
    upright, drawn = synthesize(kind, 2.0, seed=4, posture=UPRIGHT), synthesize(kind, 2.0, seed=4)
    ground = [0, 2]
    path = drawn.root_translation[:, ground] - upright.root_translation[:, ground]
    assert np.abs(path).max() < 1e-9
    ankles = [J["l_ankle"], J["r_ankle"]]
    planted = (drawn.joint_positions - upright.joint_positions)[:, ankles][..., ground]
    assert np.abs(planted).max() < 0.02  # the feet land where the kind puts them
    chest = J["spine2"]
    assert np.abs(drawn.local_rotations[:, chest] - upright.local_rotations[:, chest]).max() > 0.01


def test_a_given_posture_is_the_one_carried():
    leaning = Posture(pelvis_tilt=10 * DEG, chest_lean=-15 * DEG, collars={"l": (0.0, 0.0, 0.2)})
    upright = synthesize("idle", 2.0, seed=1, posture=UPRIGHT)
    carried = synthesize("idle", 2.0, seed=1, posture=leaning)
    pitch, lean, _ = np.subtract(_carriage(carried), _carriage(upright))
    assert pitch == pytest.approx(10.0, abs=0.5) and lean == pytest.approx(-15.0, abs=0.5)


def test_a_procedural_sequence_is_keyed_by_its_posture_and_a_files_is_not(tmp_path, monkeypatch):
    """Parts simulated from the upright clips of before are not taken for the carried ones: the
    procedural key carries the posture's version, a file's is as it was."""
    import hrr_garment.sim.plan as plan
    from hrr_garment.motion.io import save_motion

    clip = tmp_path / "clip.npz"
    save_motion(synthesize("walk", 1.0, seed=0), clip)
    procedural = SequenceSpec(name="walk_0", kind="walk", seed=0, seconds=2.0)
    from_file = SequenceSpec(name="clip", kind="file", path=str(clip), start=0, stop=30)
    keys = procedural.key({}), from_file.key({})
    monkeypatch.setattr(plan, "POSTURE_VERSION", plan.POSTURE_VERSION + 1)
    assert procedural.key({}) != keys[0] and from_file.key({}) == keys[1]
