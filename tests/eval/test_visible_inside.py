"""hrr-eval's headline plausibility figure, the cloth inside the body the viewer sees: exactly the share
of cloth placed more than 5 mm inside a skinned mesh built by hand; on the mannequin the capsule
figure itself; a character measured against the mesh its body.json carries, and unknown, and said to
be, where body.json does not carry it."""

import math

import numpy as np
import pytest

from hrr_garment.body.body_file import BodyRecord
from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.body.fit import FitReport
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.body.skinned_body import SkinnedBody
from hrr_garment.data.dataset import SequenceRecord
from hrr_garment.eval.metrics import MeshTopology
from hrr_garment.eval.report_tables import mode_table
from hrr_garment.eval.scoring import sequence_metrics
from hrr_garment.eval.visible_inside import (
    CAPSULES,
    MESH,
    UNKNOWN,
    VisibleBody,
    inside_before_and_after,
    inside_visible,
    visible_body_of,
)
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.skeleton import CANONICAL, NUM_JOINTS
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.quality import body_signed_distance, penetration_fraction
from tests.body.test_mesh_inside import box

HALF = 0.1  # the box's half side, metres


def pelvis_box() -> SkinnedBody:
    """A closed box around the pelvis, skinned to it alone: it moves rigidly with the pelvis."""
    vertices, faces = box(HALF, splits=3)
    weights = np.zeros((len(vertices), NUM_JOINTS))
    weights[:, 0] = 1.0
    return SkinnedBody(
        vertices, faces, weights, np.tile(np.eye(3), (NUM_JOINTS, 1, 1)), np.zeros((NUM_JOINTS, 3))
    )


def test_the_figure_is_the_share_of_cloth_placed_inside_a_skinned_mesh():
    motion = synthesize("walk", 1.0, seed=2)
    mesh = pelvis_box()
    # in the box's own frame: the centre, 1 cm and 8 mm inside a side, 3 mm inside (not counted),
    # and outside by 2 mm and 5 cm; 3 of 6 more than 5 mm inside on every frame
    local = np.array(
        [[0, 0, 0], [HALF - 0.01, 0.02, 0.01], [0.03, -HALF + 0.008, 0.0], [0.0, 0.02, HALF - 0.003]]
        + [[HALF + 0.002, 0.0, 0.0], [0.0, HALF + 0.05, 0.02]]
    )
    rot, trans = mesh.joint_transforms(motion.global_rotations, motion.joint_positions)
    cloth = np.einsum("tab,vb->tva", rot[:, 0], local) + trans[:, None, 0]
    visible = VisibleBody.of_mesh(mesh, DEFAULT_BODY)
    assert visible.kind == MESH and visible.closed
    np.testing.assert_array_equal(inside_visible(cloth, motion, visible), np.full(motion.num_frames, 0.5))
    # the push-out takes every point out on frame 3 and moves one point in on frame 5 (it may: the
    # figure after it is measured, not assumed): the mean after falls and rises by those frames' shares
    after = cloth.copy()
    after[3] += [0.0, 1.0, 0.0]
    after[5, 5] = after[5, 0]
    frames = motion.num_frames
    figure = inside_before_and_after(cloth, after, motion, visible=visible)
    assert figure["inside_visible_before_pct"] == figure["inside_visible_before_worst_pct"] == 50.0
    assert math.isclose(figure["inside_visible_pct"], 50.0 - 50.0 / frames + 100.0 / 6 / frames)
    assert math.isclose(figure["inside_visible_worst_pct"], 100.0 * 4 / 6)


def test_on_the_mannequin_the_figure_is_the_capsule_figure(rng):
    motion = synthesize("walk", 1.0, seed=4)
    template = make_garment("skirt", 300)
    # cloth scattered around the hips: some of it inside the capsules, deeper and shallower
    garment = motion.joint_positions[:, :1] + rng.uniform(
        -0.15, 0.15, (motion.num_frames, template.num_vertices, 3)
    )
    record = SequenceRecord("hips", garment.astype(np.float32), motion)  # no body named: the mannequin
    for body in (None, mannequin_record()):
        assert visible_body_of(body).kind == CAPSULES
    capsules = penetration_fraction(body_signed_distance(garment, motion, DEFAULT_BODY))
    assert 0 < capsules.mean() < 1
    np.testing.assert_array_equal(inside_visible(garment, motion, visible_body_of(None)), capsules)
    rest = template.vertices.astype(np.float64)
    m = sequence_metrics(
        garment, garment, record, rest, MeshTopology.of(template.faces, template.num_vertices), np.zeros(1)
    )
    # the same count (a mean of frames' shares against the share of all: equal to the last bit or so)
    assert m["inside_visible_pct"] == pytest.approx(m["penetration_5mm_pct"], rel=1e-12)
    assert m["inside_visible_pct"] == 100.0 * capsules.mean()
    assert m["inside_visible_worst_pct"] == 100.0 * capsules.max()
    assert m["inside_visible_before_pct"] == m["inside_visible_pct"]  # no push-out ran: the same cloth


def test_a_character_whose_body_file_carries_its_mesh_is_measured_against_that_mesh():
    from tests.body.test_mesh_record import _mesh

    fitted = BodyRecord(
        CANONICAL, DEFAULT_BODY, 1.0, 1.7, report=FitReport(15.0, 40.0, 0.3, 0.01), mesh=_mesh()
    )
    visible = visible_body_of(fitted)
    assert visible.kind == MESH and np.array_equal(visible.mesh.faces, fitted.mesh.faces)


def test_a_character_whose_mesh_is_not_in_its_body_file_is_unknown_and_said_to_be():
    fitted = BodyRecord(CANONICAL, DEFAULT_BODY, 1.0, 1.7, report=FitReport(15.0, 40.0, 0.3, 0.01))
    visible = visible_body_of(fitted)
    assert visible.kind == UNKNOWN and visible.mesh is None
    motion = synthesize("walk", 0.5, seed=1)
    assert np.isnan(inside_visible(np.zeros((motion.num_frames, 5, 3)), motion, visible)).all()
    metrics = {
        "inside_visible_before_pct": math.nan,
        "inside_visible_pct": math.nan,
        "inside_visible_worst_pct": math.nan,
        "penetration_pct": 2.5,
    }
    lines = mode_table({"auto": {"metrics": metrics, "visible_bodies": {UNKNOWN: 2}}})
    header, row = lines[0].split(" | "), lines[2].split(" | ")
    assert header.index("inside seen before push-out %") < header.index("in capsules %")
    assert row[header.index("inside seen %")] == "unknown" and row[header.index("in capsules %")] == "2.50"
    assert "unknown: a character fitted to a mesh that its body.json does not carry" in lines[-1]
    # a report written before the figure: n/a, not "unknown"
    assert mode_table({"auto": {"metrics": {"penetration_pct": 1.0}}})[2].count("n/a") >= 3
