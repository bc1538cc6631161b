"""The parametric body (anny): shapes span real statures, the mesh stands in the project's frame,
the fit follows it, nothing is downloaded, and hrr-body writes what it reads."""

import json

import numpy as np
import pytest

pytest.importorskip("anny", reason="the bodies extra is not installed")

pytestmark = pytest.mark.slow  # anny builds its blend shapes once (20-30 s), cached under the workspace

from hrr_garment.body.parametric import BodyShape, parametric_body  # noqa: E402
from hrr_garment.motion.skeleton import JOINT_INDEX  # noqa: E402


@pytest.fixture(scope="module")
def bodies(monkeypatch_module):
    import anny.paths

    def refuse(*args, **kwargs):
        raise AssertionError("anny tried to download its non-commercial data")

    monkeypatch_module.setattr(anny.paths, "download_noncommercial_data", refuse)
    shapes = {
        "short_heavy": BodyShape(height=0.25, weight=0.9, gender=0.0),
        "average": BodyShape(),
        "tall_slim": BodyShape(height=0.85, weight=0.15, gender=1.0),
    }
    return {name: parametric_body(shape) for name, shape in shapes.items()}


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as patch:
        yield patch


def test_statures_follow_the_height_parameter(bodies):
    statures = [bodies[n].fitted.stature for n in ("short_heavy", "average", "tall_slim")]
    assert statures == sorted(statures) and 1.35 < statures[0] < 1.6 < statures[2] < 2.0
    pelvis = [bodies[n].fitted.pelvis_height for n in ("short_heavy", "average", "tall_slim")]
    assert pelvis == sorted(pelvis)


def test_the_mesh_stands_in_the_projects_frame(bodies):
    for body in bodies.values():
        v, j = body.mesh.vertices, body.mesh.joints
        assert v[:, 1].min() == pytest.approx(0.0, abs=1e-9)  # soles on the ground
        assert abs(j[0, 0]) < 1e-9 and abs(j[0, 2]) < 1e-9  # the pelvis over the origin
        assert j[JOINT_INDEX["head"], 1] > j[0, 1] > j[JOINT_INDEX["l_knee"], 1]  # Y up
        assert j[JOINT_INDEX["l_shoulder"], 0] > 0 > j[JOINT_INDEX["r_shoulder"], 0]  # its left at +X
        assert j[JOINT_INDEX["l_foot"], 2] > j[JOINT_INDEX["l_ankle"], 2]  # toes forward, +Z
        assert len(body.mesh.faces) > 1000 and body.mesh.faces.max() < len(v)


def test_the_capsules_follow_each_body(bodies):
    for body in bodies.values():
        report = body.fitted.report
        assert report.mean_mm < 30 and report.p95_mm < 75
    heavy, slim = bodies["short_heavy"].fitted.body, bodies["tall_slim"].fitted.body
    radius = {c.name: c.radius for c in heavy.capsules}
    assert radius["belly"] > {c.name: c.radius for c in slim.capsules}["belly"]  # weight shows in the girth


def test_hrr_body_makes_and_reads_a_body_file(tmp_path, capsys):
    from hrr_garment.body.body_file import read_body
    from hrr_garment.cli.body import main

    out = tmp_path / "tall.json"
    assert main(["make", "-o", str(out), "--height", "0.85", "--weight", "0.15", "--gender", "1"]) == 0
    assert "m tall" in capsys.readouterr().out
    record = read_body(out)
    assert record.shape["height"] == 0.85 and record.report.mean_mm < 30
    assert main(["make", "-o", str(tmp_path / "bad.json"), "--height", "1.4"]) == 2
    assert (
        "height must be a number in [0, 1]" in capsys.readouterr().err
        and not (tmp_path / "bad.json").exists()
    )
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["stature_m"] == pytest.approx(
        info["measures_m"]["stature"], abs=1e-3
    )  # the measures models read


def test_the_shape_of_a_known_body_is_found_from_its_mesh():
    """anny's mesh of a known phenotype, given without it: gradient descent through anny finds the
    phenotype, and the surfaces lie within a centimetre of each other both ways (issue 45)."""
    from hrr_garment.body.parametric import anny_rest_mesh, fit_shape

    truth = BodyShape(height=0.3, weight=0.75, gender=0.2, muscle=0.6)
    mesh = anny_rest_mesh(truth)
    fit = fit_shape(mesh.vertices, mesh.faces)
    assert fit.mean_mm < 10.0 and fit.p95_mm < 20.0
    for name in ("height", "weight", "gender", "muscle"):
        assert abs(getattr(fit.shape, name) - getattr(truth, name)) < 0.05, name
    with pytest.raises(ValueError, match="finite vertices"):
        fit_shape(mesh.vertices[:10], mesh.faces)


def test_an_animation_on_a_parametric_body_previews_its_own_mesh(trained, tmp_path):
    """out.h5 keeps the body it was animated on; its preview poses the body's own mesh (anny's
    rest mesh skinned by its weights) with the clip, on the body's capsules rather than beside them."""
    from hrr_garment.body.body_file import record_of
    from hrr_garment.body.capsules import frames_signed_distance
    from hrr_garment.cli.preview import main as preview_main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.synth import synthesize

    root, _, _ = trained
    body = parametric_body(BodyShape(height=0.6))
    record = record_of(body)
    with pytest.warns(UserWarning):  # the tiny model knows the mannequin alone
        anim = Animator.load(root / "model").animate(
            synthesize("walk", 0.6, seed=0), body=record, allow_outside=True
        )
    anim.save(tmp_path / "out.h5")
    saved = read_animation_h5(tmp_path / "out.h5")
    vertices, faces = saved.body_mesh(9)
    assert len(vertices) == len(body.mesh.vertices) and np.array_equal(
        faces, body.mesh.faces
    )  # its mesh, not capsules
    a, b = record.body.pose_motion(anim.skeleton)
    gap = frames_signed_distance(vertices[None], a[9:10], b[9:10], record.body.radii)[0]
    assert np.median(np.abs(gap)) < 0.03
    assert (
        preview_main(
            [str(tmp_path / "out.h5"), "-o", str(tmp_path / "sheet.png"), "--frames", "2", "--size", "96"]
        )
        == 0
    )
