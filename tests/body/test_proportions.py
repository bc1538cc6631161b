"""A performer's proportions from the file's own rig, and the parametric body nearest to them."""

import numpy as np
import pytest

from hrr_garment.body.proportions import MEASURES, nearest_body, proportions, source_proportions
from hrr_garment.errors import InputError
from hrr_garment.motion.skeleton import JOINT_NAMES, PARENTS, REST_OFFSETS, Skeleton


def test_the_measures_of_the_mannequin_are_its_bone_lengths():
    m = proportions(Skeleton().rest_positions())
    assert m["upper_leg"] == pytest.approx(np.linalg.norm(REST_OFFSETS[4]))
    assert m["forearm"] == pytest.approx(np.linalg.norm(REST_OFFSETS[20]))
    assert m["hip_width"] == pytest.approx(2 * REST_OFFSETS[1][0])
    assert set(m) == set(MEASURES)


def test_a_rigs_proportions_come_from_the_file_whatever_it_does(tmp_path):
    """A BVH of a body 1.2 times the mannequin's, in centimetres, walking: the measures are 1.2
    times the mannequin's, though retargeting gives every clip the mannequin's bones."""
    from hrr_garment.motion.bvh_write import BvhStyle, write_bvh
    from hrr_garment.motion.synth import synthesize

    motion = synthesize("walk", 1.0, seed=1)
    path = tmp_path / "tall.bvh"
    write_bvh(
        path,
        list(JOINT_NAMES),
        list(PARENTS),
        REST_OFFSETS * 1.2 * 100,
        motion.local_rotations.astype(np.float64),
        motion.root_translation * 1.2 * 100,
        1 / 30,
        BvhStyle(unit_scale=0.01),
    )
    measured = source_proportions(path)
    mannequin = proportions(Skeleton().rest_positions())
    for name, value in measured.items():
        assert value == pytest.approx(1.2 * mannequin[name], rel=1e-4), name
    with pytest.raises(InputError, match="npz files carry none"):
        source_proportions(tmp_path / "clip.npz")


def test_measures_a_body_cannot_have_are_refused():
    for bad in ({"upper_leg": 5.0}, {"tail": 0.3}, {}, {"forearm": float("nan")}):
        with pytest.raises(ValueError, match="measures must be"):
            nearest_body(bad)


@pytest.mark.slow
def test_the_nearest_body_to_a_known_bodys_measures_is_that_body():
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    from hrr_garment.body.parametric import BodyShape, anny_rest_mesh

    truth = BodyShape(height=0.7, weight=0.3, gender=0.9)
    found = nearest_body(proportions(anny_rest_mesh(truth).joints))
    assert found.rms_mm < 2.0 and abs(found.shape.height - truth.height) < 0.05
    assert set(found.errors_mm) == set(MEASURES)


@pytest.mark.slow
def test_a_cmu_performers_nearest_body_is_reported_with_its_error(mocap_dir):
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    measured = source_proportions(mocap_dir / "cmu" / "02_01.bvh")
    assert 0.35 < measured["upper_leg"] < 0.5 and 0.35 < measured["lower_leg"] < 0.5
    found = nearest_body(measured)
    assert set(found.errors_mm) == set(measured) and np.isfinite(found.rms_mm) and found.rms_mm < 50


@pytest.mark.slow
def test_hrr_body_nearest_writes_the_performers_body(mocap_dir, tmp_path, capsys):
    pytest.importorskip("anny", reason="the bodies extra is not installed")
    from hrr_garment.body.body_file import read_body
    from hrr_garment.cli.body import main

    out = tmp_path / "performer.json"
    assert main(["nearest", str(mocap_dir / "cmu" / "02_01.bvh"), "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "mm RMS" in said and "upper_leg" in said
    record = read_body(out)
    assert record.shape is not None and 1.4 < record.stature < 2.1
    assert main(["nearest", str(tmp_path / "none.npz"), "-o", str(tmp_path / "x.json")]) == 2
