"""A procedural clip's carriage (motion/synth/posture.py): drawn per seed about the real clips'
(the pelvis pitched forward, the chest leaning back from it, the collars turned), added to the
kind's own motion without changing its steps; upright (the default) is the kind's body; a preset
asks for drawn postures, and its procedural sequences' keys say so while upright ones keep theirs."""

import dataclasses

import numpy as np
import pytest

from hrr_garment.motion.skeleton import JOINT_INDEX as J
from hrr_garment.motion.synth import UPRIGHT, Posture, synthesize
from hrr_garment.motion.synth.posture import DEG, carriage
from hrr_garment.sim.plan import LATER_FIELDS, plan_sequences


def _carriage(motion) -> tuple[float, float, float]:
    measured = carriage(motion)
    return measured.pelvis_pitch, measured.chest_lean, measured.collar


def test_drawn_postures_are_held_as_real_performers_hold_them():
    """Over 30 walks the pelvis pitches forward and the chest leans back from it, about the real
    clips' 10 deg each, and the collars turn; upright, the kind's walk has neither."""
    drawn = np.array([_carriage(synthesize("walk", 2.0, seed=s, posture="drawn")) for s in range(30)])
    upright = np.array([_carriage(synthesize("walk", 2.0, seed=s, posture=UPRIGHT)) for s in range(30)])
    assert 6.0 < drawn[:, 0].mean() - upright[:, 0].mean() < 12.0
    assert -14.0 < drawn[:, 1].mean() - upright[:, 1].mean() < -6.0
    assert drawn[:, 0].std() > 3.0 and drawn[:, 1].std() > 3.0  # a spread of carriages, not one
    assert upright[:, 2].max() < 1e-3 and 6.0 < drawn[:, 2].mean() < 16.0


def test_the_pelvis_turn_in_the_stride_is_measured_as_given():
    """The carriage's pelvis turn: a walk's pelvis turned about the vertical by 10 deg at 1 Hz reads
    its spread (10 / sqrt 2), the kinds' walk, whose pelvis never turns about its heading, 0."""
    from hrr_garment.motion.rotations import rotation_about_y

    walk = synthesize("walk", 4.0, seed=2)
    assert carriage(walk).pelvis_turn_sd < 1e-6
    turn = rotation_about_y(10 * DEG * np.sin(2 * np.pi * np.arange(walk.num_frames) / 30))
    rotations = np.array(walk.local_rotations, np.float64)
    rotations[:, J["pelvis"]] = turn @ rotations[:, J["pelvis"]]
    turned = dataclasses.replace(walk, local_rotations=rotations.astype(walk.local_rotations.dtype))
    assert carriage(turned).pelvis_turn_sd == pytest.approx(10 / np.sqrt(2), rel=0.1)


@pytest.mark.parametrize("kind", ["walk", "dance", "jump"])
def test_a_posture_keeps_the_kinds_steps(kind):
    """The posture is drawn after the kind's own draws: the same seed's ground path and feet, only
    the body above them carried otherwise."""
    upright, drawn = synthesize(kind, 2.0, seed=4), synthesize(kind, 2.0, seed=4, posture="drawn")
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


def test_a_preset_asks_for_drawn_postures_and_upright_sequences_keep_their_keys(tmp_path):
    """The quick preset's procedural sequences carry drawn postures, keyed apart from upright ones
    (parts simulated upright are not taken for them); an upright spec hashes as before the field
    existed; a preset's unknown posture is refused naming it."""
    from hrr_garment.errors import InputError
    from hrr_garment.sim.preset import load_preset, plan_record

    quick = load_preset("quick")
    specs = [s for s in plan_sequences(quick) if s.kind != "file"]
    assert specs and {s.posture for s in specs} == {"drawn"} and plan_record(quick)["posture"] == "drawn"
    assert "posture" not in plan_record(load_preset("tiny"))  # upright presets record as before
    spec = specs[0]
    upright = dataclasses.replace(spec, posture="upright")
    assert spec.key({}) != upright.key({})
    assert spec.motion().source.endswith(":posture=drawn")
    # an upright spec hashes as before the field existed (the golden keys of tests/sim/test_material_plan.py)
    assert LATER_FIELDS["posture"] == "upright"
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nvertices: 300\nseconds: 2.0\nsequences: {walk: 1}\nposture: slouched\n")
    with pytest.raises(InputError, match="slouched"):
        load_preset(str(bad))
