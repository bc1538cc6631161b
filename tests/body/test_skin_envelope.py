"""Capsules grown to hold a skin (hrr_garment.body.skin_envelope): in bent poses they hold every point
of the skin's faces, their distance never exceeds the distance to the skin, and they grow only where
the skin stands out of them (and its pieces are not carried out of them)."""

import numpy as np
import pytest

from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
from hrr_garment.body.mesh_distance import mesh_signed_distance
from hrr_garment.body.skin_envelope import SkinEnvelope
from hrr_garment.motion.synth import synthesize

from .limb import BulgingMannequin

BULGE_M = 0.05


@pytest.mark.slow  # the exact distance to a 3,360-vertex skin: 8 s
def test_grown_capsules_hold_the_posed_skin_and_bound_the_distance_to_it(rng):
    skin = BulgingMannequin(BULGE_M).skinned()
    envelope = SkinEnvelope.of(skin, DEFAULT_BODY)
    run = synthesize("run", 0.8, seed=1)
    frames = np.linspace(0, run.num_frames - 1, 4).astype(int)
    rot, pos = run.global_rotations[frames], run.joint_positions[frames]
    posed = envelope.pose(rot, pos)
    assert np.abs(posed - skin.pose(rot, pos)).max() < 1e-12  # skinning as the skinned body's
    growth = envelope.growth(rot, pos)
    names = [c.name for c in DEFAULT_BODY.capsules]
    thighs = [names.index(n) for n in ("l_thigh", "r_thigh")]
    rigid = [i for i, n in enumerate(names) if n.endswith(("arm", "hand"))]
    # at rest the thighs grow by their bulge; posed, the arms and the hands, skinned rigidly and
    # apart from the bulges, do not grow at all (each piece keeps to its capsule's joint)
    at_rest = envelope.growth(skin.rest_rotations[None], skin.rest_positions[None])[0]
    assert np.abs(at_rest[thighs] - BULGE_M).max() < 1e-6
    assert np.abs(growth[:, rigid]).max() < 1e-6 and (growth[:, thighs] >= BULGE_M - 1e-6).all()
    a, b, radii = envelope.grown(rot, pos)
    corner = rng.dirichlet(np.ones(3), size=len(skin.faces))  # a random point of every face
    for t in range(len(frames)):
        on_faces = np.einsum("fk,fkc->fc", corner, posed[t][skin.faces])
        inside = capsule_signed_distance(np.concatenate([posed[t], on_faces]), a[t], b[t], radii[t])[0]
        assert inside.max() < 1e-9
        around = posed[t][rng.integers(0, len(posed[t]), 400)] + rng.normal(scale=0.06, size=(400, 3))
        bound = capsule_signed_distance(around, a[t], b[t], radii[t])[0]
        exact = np.abs(mesh_signed_distance(around, posed[t], skin.faces))
        assert (bound <= exact + 1e-9).all()
        # and not loose: outside the body the bound is near the distance (the bulges are ~5 cm)
        outside = bound > 0.01
        assert outside.mean() > 0.3 and np.median(exact[outside] - bound[outside]) < 0.02
