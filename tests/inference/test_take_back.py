"""The push-out's take-back of a mode's additions (hrr_garment.inference.take_back), against a body
whose distance is known in closed form: one capsule along the Y axis, radius 0.1 m."""

import numpy as np
import pytest

from hrr_garment.inference.collision import PosedCapsules
from hrr_garment.inference.take_back import HALVINGS, take_back
from hrr_garment.motion.synth import synthesize
from tests.conftest import squeezed_skirt

RADIUS, MARGIN = 0.1, 0.002


def _capsule(frames: int) -> PosedCapsules:
    a = np.tile(np.array([[[0.0, -1.0, 0.0]]]), (frames, 1, 1))
    b = np.tile(np.array([[[0.0, 1.0, 0.0]]]), (frames, 1, 1))
    return PosedCapsules(a, b, np.full(1, RADIUS))


def _distance(points: np.ndarray) -> np.ndarray:
    return np.hypot(points[..., 0], points[..., 2]) - RADIUS


def test_each_addition_is_taken_back_by_the_least_share_that_clears_the_body():
    rng = np.random.default_rng(0)
    n = 200
    angle = rng.uniform(0, 2 * np.pi, n)
    out = np.stack([np.cos(angle), rng.uniform(-0.5, 0.5, n), np.sin(angle)], -1)
    base = out * np.array([0.15, 1.0, 0.15])  # 5 cm outside the capsule's side
    base[:, 1] = out[:, 1]
    inward = rng.uniform(0.06, 0.14, n)  # the additions take each vertex 1-9 cm inside
    vertices = base - inward[:, None] * out * np.array([1.0, 0.0, 1.0])
    steps = 2**HALVINGS
    taken = take_back(vertices[None], base[None], _capsule(1), MARGIN)[0]
    share = np.linalg.norm(taken - vertices, axis=-1) / np.linalg.norm(base - vertices, axis=-1)
    assert (_distance(taken) >= MARGIN - 1e-12).all()  # every vertex clear of the body
    # and by the least share to within 1 / steps: an eighth less leaves it nearer than the margin
    less = vertices + (share - 1 / steps)[:, None] * (base - vertices)
    assert (_distance(less) < MARGIN).all()
    exact = (inward - 0.05 + MARGIN) / inward  # the share that lands a vertex at the margin
    assert np.abs(share - exact).max() <= 1 / steps


def test_cloth_clear_of_the_body_and_the_regression_inside_it():
    base = np.array([[0.3, 0.0, 0.0], [0.08, 0.2, 0.0], [0.0, 0.0, 0.15]])
    vertices = np.array([[0.35, 0.0, 0.0], [0.05, 0.2, 0.0], [0.0, 0.0, 0.098]])
    taken = take_back(vertices[None], base[None], _capsule(1), MARGIN)[0]
    np.testing.assert_array_equal(taken[0], vertices[0])  # clear of the body: its addition kept
    np.testing.assert_allclose(taken[1], base[1])  # its regression inside too: back to the regression
    assert _distance(taken[2]) >= MARGIN and taken[2, 2] < base[2, 2]  # the least share, not all


def test_the_push_out_takes_the_additions_back_and_reports_the_cloth_as_it_came():
    """The tiny skirt squeezed 15 % into the hips by its additions, its regression as at rest
    (clear of the body): the push-out with that base reports the squeezed cloth as it came, and
    moves each vertex only back along its addition (not to the nearest surface), out of the body."""
    from hrr_garment.inference.collision import push_out

    motion = synthesize("idle", 0.2, seed=0)
    skirt, squeezed = squeezed_skirt(motion, 0.85)
    _, rest = squeezed_skirt(motion, 1.0)
    pushed, report = push_out(squeezed.astype(np.float32), motion, skirt.faces)
    taken, report_taken = push_out(squeezed.astype(np.float32), motion, skirt.faces, base=rest)
    assert report_taken.inside_before == pytest.approx(report.inside_before) and report.inside_before > 0.05
    assert report_taken.inside_after == 0.0
    moved, back = taken - squeezed, rest - squeezed
    length = np.linalg.norm(moved, axis=-1)
    cosine = np.einsum("tvk,tvk->tv", moved, back) / np.maximum(length * np.linalg.norm(back, axis=-1), 1e-12)
    assert (length > 1e-3).mean() > 0.05
    assert (cosine[length > 1e-3] > 0.9).mean() > 0.9  # back along the addition


@pytest.mark.parametrize("on_skin", [False, True], ids=["capsules", "visible mesh"])
def test_the_kernel_takes_back_as_the_reference(monkeypatch, on_skin):
    """The push-out's kernel (the take-back in C, each frame before its push) and the numpy
    reference agree on the frames and the report, against capsules and against a closed skin; a
    frame alone (a stream's) as in the batch."""
    from hrr_garment import native
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.inference.collision import PUSH_OUT, push_out
    from hrr_garment.inference.edge_limits import EdgeLimits
    from hrr_garment.inference.visible_push import PosedSkin, VisibleCollider
    from tests.body.limb import BulgingMannequin

    if native.load_kernel() is None:
        pytest.skip("no C compiler")
    motion = synthesize("dance", 0.3, seed=4)
    skirt, squeezed = squeezed_skirt(motion, 0.8, on_body=True)  # the additions: into the hips
    _, rest = squeezed_skirt(motion, 1.0, on_body=True)  # the regression: as worn
    squeezed, rest = squeezed.astype(np.float32), rest.astype(np.float32)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)

    closed = VisibleCollider.of(DEFAULT_BODY, BulgingMannequin(0.05).closed().skinned()) if on_skin else None

    def body(clip):
        return PosedSkin.of(closed, clip) if on_skin else DEFAULT_BODY

    got, report = push_out(squeezed, motion, skirt.faces, body=body(motion), limits=limits, base=rest)
    plain, plain_report = push_out(squeezed, motion, skirt.faces, body=body(motion), limits=limits)
    assert report.inside_before == pytest.approx(plain_report.inside_before) and report.inside_before > 0.02
    assert np.abs(got - plain).max() > 1e-3  # the take-back moved the cloth otherwise than the push
    frame = motion.slice(3, 4)
    one, _ = push_out(squeezed[3:4], frame, skirt.faces, body=body(frame), limits=limits, base=rest[3:4])
    np.testing.assert_array_equal(one[0], got[3])
    # neither the take-back nor the push stretches an edge past the push's limit on the cloth as it came
    ends = squeezed[:, limits.edges[:, 1]] - squeezed[:, limits.edges[:, 0]]
    bound = np.maximum(
        PUSH_OUT.max_strain * limits.rest_length,
        np.linalg.norm(ends, axis=-1) + PUSH_OUT.stretch_slack * limits.rest_length,
    )
    lengths = np.linalg.norm(got[:, limits.edges[:, 1]] - got[:, limits.edges[:, 0]], axis=-1)
    assert (lengths <= bound + 2e-5).all()
    monkeypatch.setattr(native, "load_kernel", lambda *args, **kwargs: None)
    ref, ref_report = push_out(squeezed, motion, skirt.faces, body=body(motion), limits=limits, base=rest)
    assert np.abs(got - ref).max() < 1e-5
    assert report.inside_before == pytest.approx(ref_report.inside_before)
    assert report.limited == ref_report.limited
    assert report.inside_after == pytest.approx(ref_report.inside_after, abs=1e-3)
