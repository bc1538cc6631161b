"""The push in the garment's subspace (hrr_garment.inference.subspace_push): cloth inside the body
comes out by a move of the basis alone, and a frame clear of the body is left as it is."""

import numpy as np
import pytest

from hrr_garment.motion.frame import to_body_frame
from hrr_garment.motion.synth import synthesize
from tests.conftest import squeezed_skirt


def _skirt_and_basis():
    """A tiny skirt and an orthonormal basis of its body-frame moves: the principal components of
    frames widened and narrowed about its axis, shifted and bent at random (a decoder's outputs)."""
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.models.subspace import principal_components

    skirt = make_garment("skirt", 300)
    rng = np.random.default_rng(7)
    rest = skirt.vertices.astype(np.float64)
    axis = rest.mean(0)
    radial = rest - axis
    radial[:, 1] = 0.0
    frames = []
    for _ in range(96):
        height = (rest[:, 1] - rest[:, 1].min())[:, None]
        bend = rng.normal(scale=0.05, size=3) * height  # the hem swung further than the waist
        frames.append(rest + rng.normal(scale=0.15) * radial + rng.normal(scale=0.02, size=3) + bend)
    _, basis, _ = principal_components(np.stack(frames).astype(np.float32), 8)
    return skirt, basis


def _squeezed_walk():
    """The tiny skirt and its basis, a walk, and the skirt 20 % narrower worn through it (float32):
    into the hips."""
    skirt, basis = _skirt_and_basis()
    motion = synthesize("walk", 0.3, seed=2)
    _, squeezed = squeezed_skirt(motion, 0.8, on_body=True)
    return skirt, basis, motion, squeezed.astype(np.float32)


def test_the_subspace_push_takes_the_cloth_out_along_the_basis_alone():
    from hrr_garment.body.capsules import DEFAULT_BODY, frames_signed_distance
    from hrr_garment.inference.subspace_push import SubspacePush

    skirt, basis = _skirt_and_basis()
    motion = synthesize("walk", 0.3, seed=2)
    _, squeezed = squeezed_skirt(motion, 0.8, on_body=True)  # 20 % narrower: into the hips
    squeezed = squeezed.astype(np.float32)
    squeezed[-1, :, 0] += 1.0  # the last frame a metre clear of the body
    a, b = DEFAULT_BODY.pose_motion(motion)
    push = SubspacePush.of(basis, skirt.vertices, skirt.edges())
    moved = push(squeezed, motion, (a, b, DEFAULT_BODY.radii), margin=0.002)
    assert moved.dtype == np.float32 and moved.shape == squeezed.shape
    before = frames_signed_distance(squeezed[:-1].astype(np.float64), a[:-1], b[:-1], DEFAULT_BODY.radii)[0]
    after = frames_signed_distance(moved[:-1].astype(np.float64), a[:-1], b[:-1], DEFAULT_BODY.radii)[0]
    depth = lambda d: np.maximum(-d, 0.0).sum()  # noqa: E731
    assert (before < -0.005).mean() > 0.05 and (after < -0.005).mean() < 0.7 * (before < -0.005).mean()
    assert depth(after) < 0.5 * depth(before)  # what of the cloth is still inside, the basis cannot reach
    assert np.array_equal(moved[-1], squeezed[-1])  # nothing near the body: untouched
    # the move, in the body frame, lies in the basis's span (float32 rounding aside)
    step = to_body_frame(moved.astype(np.float64), motion) - to_body_frame(
        squeezed.astype(np.float64), motion
    )
    flat = step.reshape(len(step), -1)
    residual = flat - (flat @ basis.T.astype(np.float64)) @ basis.astype(np.float64)
    assert np.abs(flat).max() > 0.01 and np.abs(residual).max() < 1e-5
    # a frame's move does not depend on the others it is pushed with
    one = push(squeezed[2:3], motion.slice(2, 3), (a[2:3], b[2:3], DEFAULT_BODY.radii), margin=0.002)
    assert np.array_equal(one[0], moved[2])


def test_the_stretch_weight_keeps_the_cloth_from_stretching():
    """Weighting the edges' stretch trades depth for a move that keeps the cloth's edge lengths."""
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.inference.subspace_push import SubspacePush
    from hrr_garment.sim.quality import edge_strain

    skirt, basis = _skirt_and_basis()
    motion = synthesize("walk", 0.2, seed=2)
    _, squeezed = squeezed_skirt(motion, 0.8, on_body=True)
    squeezed = squeezed.astype(np.float32)
    capsules = (*DEFAULT_BODY.pose_motion(motion), DEFAULT_BODY.radii)
    loose = SubspacePush.of(basis, skirt.vertices, skirt.edges(), strain_weight=0.0)(
        squeezed, motion, capsules, 0.002
    )
    stiff = SubspacePush.of(basis, skirt.vertices, skirt.edges(), strain_weight=100.0)(
        squeezed, motion, capsules, 0.002
    )
    edges = skirt.edges()

    def stretch(v):
        return np.abs(
            edge_strain(v, skirt.vertices, edges) - edge_strain(squeezed, skirt.vertices, edges)
        ).mean()

    assert stretch(stiff) < stretch(loose)


def test_the_push_out_runs_the_subspace_push_the_same_in_the_kernel_and_in_numpy(monkeypatch):
    """push_out with the subspace push: the kernel (each frame moved, pushed and limited in turn)
    and the numpy reference agree, and a frame streamed alone is the same bits as in a batch."""
    import dataclasses

    from hrr_garment import native
    from hrr_garment.inference.collision import PUSH_OUT, EdgeLimits, push_out
    from hrr_garment.inference.subspace_push import SubspacePush

    if native.load_kernel() is None:
        pytest.skip("no C compiler")
    skirt, basis, motion, squeezed = _squeezed_walk()
    settings = dataclasses.replace(PUSH_OUT, subspace=SubspacePush.of(basis, skirt.vertices, skirt.edges()))
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    plain, _ = push_out(squeezed, motion, skirt.faces, limits=limits)
    got, report = push_out(squeezed, motion, skirt.faces, limits=limits, settings=settings)
    assert np.abs(got - plain).max() > 0.005 and report.inside_after < 0.01
    one, _ = push_out(
        squeezed[3:4], motion.slice(3, 4), skirt.faces, limits=limits, settings=settings, report=False
    )
    assert np.array_equal(one[0], got[3])
    monkeypatch.setattr(native, "load_kernel", lambda *args, **kwargs: None)
    reference, _ = push_out(squeezed, motion, skirt.faces, limits=limits, settings=settings)
    assert np.abs(got - reference).max() < 1e-5


def test_against_the_visible_mesh_the_subspace_push_measures_the_skin(monkeypatch):
    """On a body with a mesh of its own (closed, bulging past its capsules) the subspace move measures
    the skin and takes the cloth out of it; push_out runs it the same in the kernel and in numpy, and
    a frame alone is the same bits as in a batch."""
    import dataclasses

    from hrr_garment import native
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.inference.collision import PUSH_OUT, EdgeLimits, push_out
    from hrr_garment.inference.subspace_push import SubspacePush
    from hrr_garment.inference.visible_push import PosedSkin, VisibleCollider
    from tests.body.limb import BulgingMannequin

    if native.load_kernel() is None:
        pytest.skip("no C compiler")
    skirt, basis, motion, squeezed = _squeezed_walk()
    skin = PosedSkin.of(VisibleCollider.of(DEFAULT_BODY, BulgingMannequin(0.05).closed().skinned()), motion)
    push = SubspacePush.of(basis, skirt.vertices, skirt.edges())
    on_skin = push(squeezed, motion, skin, 0.002)
    on_capsules = push(squeezed, motion, (*DEFAULT_BODY.pose_motion(motion), DEFAULT_BODY.radii), 0.002)

    def depth(frames):  # how deep the cloth lies inside the skin, summed over its vertices
        return np.maximum(-skin.distance(frames.astype(np.float64), slice(None), 0.005)[0], 0.0).sum()

    assert depth(on_skin) < 0.7 * depth(squeezed)
    # the report's count of the cloth as it came: the skin's own, measured where a hull is that deep
    counted = (skin.distance(squeezed.astype(np.float64), slice(None), 0.002)[0] < -0.005).mean(1)
    assert counted.max() > 0.05 and np.array_equal(
        skin.deeper_inside(squeezed.astype(np.float64), 0.005, 0.002), counted
    )
    assert not np.array_equal(on_skin, on_capsules)  # another body measured: another move
    settings = dataclasses.replace(PUSH_OUT, subspace=push)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    got, report = push_out(squeezed, motion, skirt.faces, body=skin, limits=limits, settings=settings)
    mesh_alone, _ = push_out(squeezed, motion, skirt.faces, body=skin, limits=limits)
    assert np.abs(got - mesh_alone).max() > 0.005 and report.inside_after < 0.01
    one_skin = PosedSkin.of(skin.bodies[0], motion.slice(3, 4))
    one, _ = push_out(
        squeezed[3:4],
        motion.slice(3, 4),
        skirt.faces,
        body=one_skin,
        limits=limits,
        settings=settings,
        report=False,
    )
    assert np.array_equal(one[0], got[3])
    monkeypatch.setattr(native, "load_kernel", lambda *args, **kwargs: None)
    reference, reported = push_out(squeezed, motion, skirt.faces, body=skin, limits=limits, settings=settings)
    assert np.abs(got - reference).max() < 1e-5 and reported.inside_after == pytest.approx(
        report.inside_after
    )


def test_a_stream_with_the_subspace_push_equals_the_offline_animation_and_changes_it(animator):
    """``push="subspace"`` runs the same in a stream, a crowd and offline, and is not the mesh push;
    a push that is neither is refused."""
    from hrr_garment.inference.run_settings import RunSettings

    motion = synthesize("dance", 1.0, seed=3)
    offline = animator.animate(motion, mode="regression", causal=True, push="subspace")
    assert offline.settings["push"] == "subspace"
    stream = animator.stream(mode="regression", push="subspace")
    streamed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(streamed - offline.vertices).max() <= 1e-5
    crowd = animator.crowd(mode="regression", push="subspace", device="native")
    crowded = np.stack(
        [
            crowd.push_motions({"a": motion.slice(t, t + 1), "b": motion.slice(t, t + 1)})[0]
            for t in range(motion.num_frames)
        ]
    )
    assert np.abs(crowded - offline.vertices).max() <= 1e-5
    mesh = animator.animate(motion, mode="regression", causal=True)
    assert np.abs(mesh.vertices - offline.vertices).max() > 0  # the subspace moved the cloth first
    with pytest.raises(ValueError, match="push must be one of"):
        RunSettings(push="sideways")


def test_the_report_counts_the_cloth_inside_as_decoded_before_the_subspace_push():
    import dataclasses

    from hrr_garment.inference.collision import PUSH_OUT, push_out
    from hrr_garment.inference.subspace_push import SubspacePush

    skirt, basis = _skirt_and_basis()
    motion = synthesize("walk", 0.2, seed=2)
    _, squeezed = squeezed_skirt(motion, 0.8, on_body=True)
    squeezed = squeezed.astype(np.float32)
    _, mesh = push_out(squeezed, motion, skirt.faces)
    settings = dataclasses.replace(PUSH_OUT, subspace=SubspacePush.of(basis, skirt.vertices, skirt.edges()))
    _, both = push_out(squeezed, motion, skirt.faces, settings=settings)
    assert both.inside_before == mesh.inside_before > 0.05 and both.worst_before == mesh.worst_before


def _torch_stage_case():
    """The subspace push's torch stage (torch_subspace_push.SubspacePushStage) on a squeezed skirt, its
    inputs relative to the pelvis as the step gives them, the pelvis, and the numpy reference's result."""
    import torch

    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.inference.subspace_push import SubspacePush
    from hrr_garment.inference.torch_capsules import capsule_distance_within
    from hrr_garment.inference.torch_subspace_push import SubspacePushStage
    from hrr_garment.motion.frame import body_heading

    skirt, basis = _skirt_and_basis()
    motion = synthesize("walk_curve", 0.3, seed=4)
    _, squeezed = squeezed_skirt(motion, 0.8, on_body=True)
    squeezed = squeezed.astype(np.float32)
    squeezed[-1, :, 0] += 1.0  # a frame clear of the body
    a, b = DEFAULT_BODY.pose_motion(motion)
    push = SubspacePush.of(basis, skirt.vertices, skirt.edges())
    theirs = push(squeezed, motion, (a, b, DEFAULT_BODY.radii), margin=0.002)
    assert np.abs(theirs - squeezed).max() > 0.01  # the reference moved the cloth
    yaw, _ = body_heading(motion)
    centre = motion.joint_positions[:, :1]
    radii = torch.tensor(DEFAULT_BODY.radii, dtype=torch.float32)

    class Stage(torch.nn.Module):  # the stage with its distance, as the exported step holds it
        def __init__(self):
            super().__init__()
            self.stage = SubspacePushStage(push, margin=0.002)

        def forward(self, p, a, b, cos, sin):
            reach = self.stage.reach  # the normals where the subspace push reads them

            def distance(q, a, b):
                return capsule_distance_within(q, a, b, radii=radii, within=reach)

            return self.stage(p, a, b, (cos, sin), distance)

    f32 = lambda x: torch.from_numpy(np.asarray(x, np.float32))  # noqa: E731
    inputs = (f32(squeezed - centre), f32(a - centre), f32(b - centre), f32(np.cos(yaw)), f32(np.sin(yaw)))
    return Stage(), inputs, centre, theirs


def test_the_torch_stage_moves_as_the_reference_does():
    """The subspace push as a GPU crowd runs it (torch_subspace_push.SubspacePushStage: every vertex's
    row weighted, one batched solve, float32) against the numpy reference (the rows near the body,
    frame by frame, float64)."""
    import torch

    stage, inputs, centre, theirs = _torch_stage_case()
    with torch.no_grad():
        moved = stage(*inputs)
    assert np.abs(moved.numpy() + centre - theirs).max() < 2e-5  # the stage moved it as the reference
    assert torch.equal(moved[-1], inputs[0][-1])  # nothing near the body: untouched


@pytest.mark.slow  # torch.export's trace takes about 8 s
def test_the_exported_stage_moves_as_the_reference_does():
    """The subspace push as an ONNX export holds it (traced by torch.export, the solve a Cholesky
    factorisation in loops) against the numpy reference."""
    import torch

    stage, inputs, centre, theirs = _torch_stage_case()
    with torch.no_grad():
        traced = torch.export.export(stage, inputs).module()(*inputs)
    assert np.abs(traced.numpy() + centre - theirs).max() < 2e-5
