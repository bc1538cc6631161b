"""A garment of your own modelled on another body: declared with that body (--made-for) it keeps
its authored shape on it and simulates there; carried onto a third body it keeps its distance from
that body; placed rigidly on the mannequin (--fit) instead, it would not fit."""

import numpy as np
import pytest

from hrr_garment.body.body_file import BodyRecord, write_body
from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
from hrr_garment.cli.simulate import main as simulate_main
from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.garment.obj import write_obj
from hrr_garment.garment.templates import make_garment
from tests.garment.test_templates_on_bodies import _larger_body

pytestmark = pytest.mark.sim


def _distance(vertices, body) -> np.ndarray:
    a, b = body.rest_pose()
    return capsule_signed_distance(np.asarray(vertices, np.float64), a, b, radii=body.radii)[0]


def _inside(vertices, body) -> float:
    return float((_distance(vertices, body) < 0).mean())


@pytest.fixture(scope="module")
def modelled(tmp_path_factory):
    """A dress modelled on a body 12 % taller and a quarter fuller than the mannequin, as an OBJ in
    that body's frame, and that body as body.json."""
    folder = tmp_path_factory.mktemp("made_for")
    body = _larger_body(1.12, 1.25)
    dress = make_garment("dress", 300, body=body)
    obj = write_obj(folder / "hero_dress.obj", dress.vertices, dress.faces, groups={"band": dress.attached})
    body_file = write_body(
        folder / "hero.json", BodyRecord(body.skeleton, body, body.pelvis_height, stature=1.9)
    )
    return folder, body, dress, obj, body_file


def _simulate(folder, obj, *extra):
    out = folder / f"{len(list(folder.glob('*.h5')))}.h5"
    args = [
        "--template",
        str(obj),
        "--attached",
        "band",
        "--preset",
        "tiny",
        "--motions",
        "walk",
        "--seconds",
        "1.0",
        "--jobs",
        "1",
        "--no-preview",
        "--quiet",
        "-o",
        str(out),
        *extra,
    ]
    assert simulate_main(args) == 0
    return GarmentDataset(out)


def test_declared_with_its_body_the_garment_keeps_its_shape_and_simulates(modelled, capsys):
    folder, body, dress, obj, body_file = modelled
    # on the mannequin as it stands, it would not fit: its band floats off the mannequin's body
    band = dress.attached
    assert (
        np.median(_distance(dress.vertices[band], DEFAULT_BODY) - _distance(dress.vertices[band], body))
        > 0.01
    )
    ds = _simulate(folder, obj, "--made-for", str(body_file))
    assert "the garment on body made_for" in capsys.readouterr().out
    (name,) = ds.names
    rest = ds.rest(name)
    on = ds.bodies[ds.body_name_of[name]].body
    assert _inside(rest, on) <= 0.01
    assert (
        np.linalg.norm(rest - dress.vertices, axis=-1).mean() <= 0.003
    )  # its authored shape, within 3 mm on average
    stats = ds.sequence(name).info["stats"]
    # a 300-vertex dress at the tiny preset's settings (its bar on real clips is tools/sim_report.py's 1.15)
    assert stats["strain_p99"] < 1.2 and stats["penetration_max"] < 0.02


def test_carried_onto_another_body_it_keeps_its_distance(modelled):
    folder, body, dress, obj, body_file = modelled
    other = _larger_body(0.95, 0.9)
    other_file = write_body(
        folder / "small.json", BodyRecord(other.skeleton, other, other.pelvis_height, stature=1.6)
    )
    ds = _simulate(folder, obj, "--made-for", str(body_file), "--body", str(other_file))
    (name,) = ds.names
    assert ds.body_name_of[name] == "small"
    rest = ds.rest(name)
    a0, b0 = body.rest_pose()
    a1, b1 = ds.bodies["small"].body.rest_pose()
    before = capsule_signed_distance(dress.vertices.astype(np.float64), a0, b0, radii=body.radii)[0]
    after = capsule_signed_distance(rest.astype(np.float64), a1, b1, radii=ds.bodies["small"].body.radii)[0]
    assert after.min() > 0 and np.median(np.abs(after - before)) < 0.003
    assert ds.sequence(name).info["stats"]["strain_p99"] < 1.2


def test_made_for_goes_with_a_template_of_your_own_and_not_with_fit(modelled, capsys):
    folder, _, _, obj, body_file = modelled
    assert (
        simulate_main(
            [
                "--garment",
                "dress",
                "--made-for",
                str(body_file),
                "--preset",
                "tiny",
                "-o",
                str(folder / "x.h5"),
            ]
        )
        == 2
    )
    assert "--template" in capsys.readouterr().err
    assert (
        simulate_main(
            [
                "--template",
                str(obj),
                "--attached",
                "band",
                "--fit",
                "--made-for",
                str(body_file),
                "--preset",
                "tiny",
                "-o",
                str(folder / "y.h5"),
            ]
        )
        == 2
    )
    assert "carried, not moved" in capsys.readouterr().err
    assert not (folder / "x.h5").exists() and not (folder / "y.h5").exists()
