"""Templates made for a body other than the mannequin: heights between the body's landmarks, the
ray-marched fit against that body's capsules, the attached band on it; the mannequin's unchanged."""

import hashlib

import numpy as np
import pytest

from hrr_garment.body.capsules import capsule_signed_distance
from hrr_garment.body.fit import fit_body, scaled_capsules
from hrr_garment.garment.templates import GARMENT_NAMES, make_garment
from hrr_garment.motion.skeleton import REST_OFFSETS, Skeleton
from tests.body.test_fit import _surface


def _larger_body(scale: float, fuller: float):
    """The mannequin's capsule surface on bones ``scale`` times longer with ``fuller`` radii,
    standing on the ground, fitted as a body."""
    skeleton = Skeleton(offsets=(REST_OFFSETS * scale).astype(np.float32))
    joints = skeleton.rest_positions(np.array([0.0, 1.0, 0.0]))
    surface = _surface(scaled_capsules(skeleton, joints).scaled(fuller), joints)
    floor = np.array([0.0, surface[:, 1].min(), 0.0])
    return fit_body(surface - floor, joints - floor).body


@pytest.mark.slow  # every template made at 1,000 vertices and the dress at 4,000: 5 to 10 s
def test_the_mannequins_templates_are_those_it_was_trained_on():
    """The templates of every dataset and model so far: vertices and attached groups as 31b4ef9 made them."""
    digest = {
        name: hashlib.sha1(make_garment(name, 1000).vertices.tobytes()).hexdigest()[:10]
        for name in GARMENT_NAMES
    }
    assert digest == {
        "dress": "9504728f1e",
        "skirt": "f5a1670a57",
        "pleated_skirt": "f0011f344a",
        "asymmetric_skirt": "2a8a7490de",
    }
    band = make_garment("dress", 4000).groups["waistband"]
    assert hashlib.sha1(band.tobytes()).hexdigest()[:10] == "ac8c9fb768"


@pytest.mark.parametrize("name", ["skirt", "dress", "asymmetric_skirt"])
def test_a_template_made_for_a_larger_body_fits_that_body(name):
    body = _larger_body(1.12, 1.25)
    a, b = body.rest_pose()
    garment = make_garment(name, 400, body=body)
    d = capsule_signed_distance(garment.vertices.astype(np.float64), a, b, radii=body.radii)[0]
    assert d.min() > 0.005  # nothing inside the body
    assert np.median(d[garment.groups["waistband"]]) == pytest.approx(
        0.012, abs=0.001
    )  # the band on it, at the gap
    mannequin = make_garment(name, 400)
    grown = garment.vertices[:, 1].max() / mannequin.vertices[:, 1].max()
    assert grown == pytest.approx(body.pelvis_height / 0.96, rel=0.06)  # its top rises with the body
