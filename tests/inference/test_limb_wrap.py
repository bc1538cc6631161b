"""The push-out's wrap (hrr_garment.inference.limb_wrap): a patch deep in a limb comes out with its
arc lengths kept, where pushing each vertex straight out stretches it by r / (r - d); the kernel's
push with the wrap is the reference's."""

import dataclasses

import numpy as np
import pytest

from hrr_garment.motion.synth import synthesize
from tests.conftest import squeezed_skirt

RADIUS, MARGIN = 0.06, 0.002


def _sheet(depth: float, spacing: float = 0.01):
    """A flat grid sheet in the plane y = RADIUS - depth, crossing a capsule along z of RADIUS
    (its ends far away): points (N, 3), edges (E, 2), and the capsule's ends and radius."""
    xs, zs = np.arange(-15, 16) * spacing, np.arange(-10, 11) * spacing
    x, z = np.meshgrid(xs, zs, indexing="ij")
    points = np.stack([x, np.full_like(x, RADIUS - depth), z], -1).reshape(-1, 3)
    idx = np.arange(len(points)).reshape(len(xs), len(zs))
    edges = np.concatenate([np.stack([idx[:-1].ravel(), idx[1:].ravel()], 1), np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1)])
    return points, edges, np.array([[0.0, 0.0, -1.0]]), np.array([[0.0, 0.0, 1.0]]), np.array([RADIUS])


def _strain(points, moved, edges):
    rest = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    return np.linalg.norm(moved[edges[:, 0]] - moved[edges[:, 1]], axis=1) / rest


@pytest.mark.parametrize("depth", [0.015, 0.03])
def test_a_patch_deep_in_a_limb_is_wrapped_onto_it_without_stretching_around_it(depth):
    from hrr_garment.inference.limb_wrap import wrap_displacements

    points, edges, a, b, radii = _sheet(depth)
    d = np.linalg.norm(points[:, :2], axis=1) - RADIUS
    wrapped = points + wrap_displacements(points, a, b, radii, d, MARGIN, edges)
    # straight out: each vertex radially onto the surface
    rho = np.linalg.norm(points[:, :2], axis=1)
    straight = points.copy()
    hit = d < MARGIN
    straight[hit, :2] *= ((RADIUS + MARGIN) / rho[hit])[:, None]
    after = np.linalg.norm(wrapped[:, :2], axis=1)
    assert np.allclose(after[hit], RADIUS + MARGIN) and np.array_equal(wrapped[~hit], points[~hit])  # on the surface; the rest kept
    assert np.allclose(wrapped[:, 2], points[:, 2])  # square to the axis: nothing slides along it
    # the deepest patch stretched straight out by about r / (r - d) (2 at half the radius); wrapped,
    # its edges around the limb keep their length (the most-stretched edges are where the sheet enters)
    worst_straight, worst_wrapped = _strain(points, straight, edges).max(), _strain(points, wrapped, edges).max()
    assert worst_straight > 0.95 * RADIUS / (RADIUS - depth)
    assert worst_wrapped < 1.45 and worst_wrapped < worst_straight - 0.1
    # the patch stays on its own side: its centre direction is +y, where it was
    assert wrapped[hit, 1].min() > 0


def test_two_patches_on_one_limb_each_keep_their_side():
    from hrr_garment.inference.limb_wrap import wrap_displacements

    front, edges, a, b, radii = _sheet(0.02)
    back = front * np.array([1.0, -1.0, 1.0])  # the mirror sheet on the other side: another patch
    points = np.concatenate([front, back])
    both = np.concatenate([edges, edges + len(front)])
    d = np.linalg.norm(points[:, :2], axis=1) - RADIUS
    wrapped = points + wrap_displacements(points, a, b, radii, d, MARGIN, both)
    hit = d < MARGIN
    assert (np.sign(wrapped[hit, 1]) == np.sign(points[hit, 1])).all()
    assert _strain(points, wrapped, both).max() < 1.45


def test_the_wrapped_push_is_the_same_without_the_kernel(monkeypatch):
    from hrr_garment import native
    from hrr_garment.inference.collision import PUSH_OUT, EdgeLimits, push_out

    if native.load_kernel() is None:
        pytest.skip("no C compiler")
    motion = synthesize("dance", 0.3, seed=4)
    skirt, squeezed = squeezed_skirt(motion, 0.8)  # into the hips and thighs
    squeezed = squeezed.astype(np.float32)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    wrapped, straight = dataclasses.replace(PUSH_OUT, wrap=True), dataclasses.replace(PUSH_OUT, max_strain=np.inf)
    native_out, native_report = push_out(squeezed, motion, skirt.faces, limits=limits, settings=wrapped)
    native_straight, _ = push_out(squeezed, motion, skirt.faces, limits=limits, settings=straight)
    monkeypatch.setattr(native, "load_kernel", lambda *args, **kwargs: None)
    numpy_out, numpy_report = push_out(squeezed, motion, skirt.faces, limits=limits, settings=wrapped)
    assert native_report.inside_before > 0.05 and native_report.inside_after < native_report.inside_before / 2
    assert np.abs(native_out - native_straight).max() > 1e-3  # the wrap is another push
    assert np.abs(native_out - numpy_out).max() < 1e-5
    assert native_report.inside_after == pytest.approx(numpy_report.inside_after, abs=0.01)
