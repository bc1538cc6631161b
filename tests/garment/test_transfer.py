"""A garment carried from one body to another: the same topology, each vertex as far off the new
body as it was off the old, nothing inside it, and the same body giving the garment back."""

import numpy as np
import pytest

from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
from hrr_garment.garment.templates import make_garment
from hrr_garment.garment.transfer import MIN_GAP_M, transfer_garment
from tests.garment.test_templates_on_bodies import _larger_body


def _distance(vertices, body):
    a, b = body.rest_pose()
    return capsule_signed_distance(np.asarray(vertices, np.float64), a, b, radii=body.radii)[0]


def test_onto_the_same_body_the_garment_stays_where_it_was():
    garment = make_garment("skirt", 300)
    same, report = transfer_garment(garment, made_for=DEFAULT_BODY, body=DEFAULT_BODY)
    assert np.abs(same.vertices - garment.vertices).max() < 1e-5
    assert report.inside == 0.0 and report.gap_change_mean_mm < 0.01


@pytest.mark.parametrize("scale, fuller", [(1.12, 1.25), (0.9, 0.85)])
def test_on_another_body_each_vertex_keeps_its_distance_from_the_body(scale, fuller):
    garment = make_garment("dress", 400)
    body = _larger_body(scale, fuller)
    moved, report = transfer_garment(garment, made_for=DEFAULT_BODY, body=body)
    assert np.array_equal(moved.faces, garment.faces) and moved.vertices.shape == garment.vertices.shape
    assert all(np.array_equal(moved.groups[g], garment.groups[g]) for g in garment.groups)
    new, old = _distance(moved.vertices, body), _distance(garment.vertices, DEFAULT_BODY)
    assert new.min() >= MIN_GAP_M - 1e-4  # nothing inside, nothing closer than the minimum gap
    assert np.median(np.abs(new - old)) < 0.003  # neither floats nor sinks
    hem = garment.groups["hem"]
    # the hem keeps its place along the legs: heights scale with the body
    assert moved.vertices[hem, 1].mean() == pytest.approx(garment.vertices[hem, 1].mean() * scale, rel=0.05)
    # and the cloth does not tear between capsules: no edge more than doubles or halves
    e = garment.edges()
    ratio = np.linalg.norm(np.diff(moved.vertices[e], axis=1), axis=-1) / np.linalg.norm(
        np.diff(garment.vertices[e], axis=1), axis=-1
    )
    assert 0.5 < ratio.min() and ratio.max() < 2.0


def test_bodies_of_other_capsules_are_refused():
    body = DEFAULT_BODY
    fewer = type(body)(body.capsules[:-1])
    with pytest.raises(ValueError, match="same capsules"):
        transfer_garment(make_garment("skirt", 200), made_for=body, body=fewer)
