"""The push-out against the mesh the viewer sees (hrr_garment.inference.visible_push): the skin's
hulls hold the skin in every pose (the kernel's are the envelope's); the reference's cull of a
closed mesh is its reference's, cell for cell, and leaves out only points outside the mesh and
farther than the margin; the kernel's broad phase (columns and a ray) leaves out exactly those the
exact test does; the kernel pushes
exactly as the numpy reference does (an open mesh and a closed one), a frame at a time as in
batches, a crowd of two bodies as each alone, and reports the cloth inside after its strain limit as
the reference measures it; a vertex deep inside is pushed out and a far one left as it was; and the
cloth ends outside the visible mesh where the capsules' push-out leaves it inside the thighs'
bulges."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from hrr_garment.body.capsules import DEFAULT_BODY, frames_signed_distance
from hrr_garment.body.mesh_distance import mesh_signed_distance, within_reach
from hrr_garment.body.mesh_inside import inside_deeper_than, mesh_inside
from hrr_garment.body.skin_cells import skin_cells
from hrr_garment.inference.collision import PushOutSettings, _push_frames, mean_operator, push_out
from hrr_garment.inference.edge_limits import EdgeLimits
from hrr_garment.inference.torch_skin_hulls import SkinHulls
from hrr_garment.inference.visible_push import CELL_M, COLUMN_M, PosedSkin, VisibleCollider
from hrr_garment.motion.synth import synthesize
from tests.body.limb import BulgingMannequin
from tests.conftest import squeezed_skirt

SETTINGS = PushOutSettings(depth=0.005)


@pytest.fixture(scope="module")
def visible():
    return VisibleCollider.of(DEFAULT_BODY, BulgingMannequin(0.05).skinned())


@pytest.fixture(scope="module")
def closed_visible():
    """The same body with its capsules' poles welded: closed, so the push-out's broad phase runs."""
    return VisibleCollider.of(DEFAULT_BODY, BulgingMannequin(0.05).closed().skinned())


def _kernel_or_skip():
    from hrr_garment.native import load_kernel

    if load_kernel() is None:
        pytest.skip("no C compiler")


@pytest.fixture(scope="module")
def skirt_frames():
    """A dance, and the tiny skirt worn on the body, 5 % narrower: into the hips and the bulges."""
    motion = synthesize("dance", 0.3, seed=4)
    skirt, frames = squeezed_skirt(motion, 0.95, on_body=True)
    return motion, skirt, frames


def _inside(visible, motion, frames, depth=SETTINGS.depth):
    """(T,) the fraction of vertices more than ``depth`` inside the posed visible mesh, exactly (the
    winding number, then the distance of the points inside alone)."""
    skin = visible.collider.body
    posed = skin.pose(motion.global_rotations, motion.joint_positions)
    return inside_deeper_than(frames.astype(np.float64), posed, skin.faces, depth=depth).mean(-1)


def test_the_hulls_hold_the_skin(visible):
    motion = synthesize("jump", 0.5, seed=1)
    posed = PosedSkin.of(visible, motion)
    skin = visible.collider.body.pose(motion.global_rotations, motion.joint_positions)
    d, _ = frames_signed_distance(skin, posed.hulls.a, posed.hulls.b, posed.hulls.radii)
    assert d.max() <= 1e-9  # every vertex of the posed skin in a hull, to rounding (so every face: convexity)
    assert (posed.hulls.radii >= DEFAULT_BODY.radii).all()
    # the kernel's hulls (where there is one) are the envelope's, its reference
    growth = visible.envelope.growth(motion.global_rotations, motion.joint_positions)
    reference = np.maximum(DEFAULT_BODY.radii + growth, DEFAULT_BODY.radii)
    assert np.abs(posed.hulls.radii - reference).max() < 1e-12
    thighs = [i for i, c in enumerate(DEFAULT_BODY.capsules) if c.name.endswith("thigh")]
    assert (posed.hulls.radii[:, thighs] > DEFAULT_BODY.radii[thighs] + 0.03).all()  # widened over the bulge


def test_the_broad_phase_is_its_reference_and_culls_only_far_outside(visible, closed_visible):
    _kernel_or_skip()
    assert closed_visible.closed and not visible.closed  # the open mesh measures every point
    motion = synthesize("dance", 0.3, seed=4)
    skin, margin = closed_visible.collider.body, SETTINGS.margin
    rng = np.random.default_rng(0)
    for t in (0, motion.num_frames // 2):
        rot, pos = motion.global_rotations[t], motion.joint_positions[t]
        cells = closed_visible.cells(rot, pos, margin)  # the kernel's
        moves = skin.joint_transforms(rot[None], pos[None])
        posed = closed_visible.kernel.pose_frames(*(np.ascontiguousarray(m) for m in moves))[0]
        reference = skin_cells(posed, skin.faces, margin=margin, cell=CELL_M)
        assert np.array_equal(cells.cells, reference.cells) and np.array_equal(cells.dims, reference.dims)
        points = rng.uniform(posed.min(0) - 0.1, posed.max(0) + 0.1, (3000, 3))
        far = cells.far(points)
        # the exact answers: the closed mesh's ray count (tests/body/test_mesh_inside.py: the winding
        # number's) and every face within a reach tried
        outside = ~mesh_inside(points, posed, skin.faces, closed=True)
        # left out: outside the mesh and farther than the margin ...
        assert (outside & ~within_reach(points, posed, skin.faces, reach=margin))[far].all()
        # ... and nearly every point 5 cm or more outside is left out
        assert far[outside & ~within_reach(points, posed, skin.faces, reach=0.05)].mean() > 0.95


def test_the_kernels_broad_phase_leaves_out_exactly_the_points_far_outside(closed_visible):
    """The push-out's own broad phase (the columns and a ray along x): a point is left out exactly
    where no triangle lies within the margin and it is outside the mesh (numpy's count along a ray of
    another direction: on this closed mesh the winding number), on points all about the body and
    within a few millimetres of its skin."""
    _kernel_or_skip()
    motion = synthesize("dance", 0.3, seed=4)
    skin, margin = closed_visible.collider.body, SETTINGS.margin
    rng = np.random.default_rng(1)
    for t in (0, motion.num_frames // 2):
        rot, pos = motion.global_rotations[t], motion.joint_positions[t]
        posed = closed_visible.posed(rot[None], pos[None])[0]
        tri = posed[skin.faces]
        on_skin = tri[rng.integers(len(tri), size=2000)].mean(1) + rng.normal(0.0, 0.004, (2000, 3))
        points = np.concatenate([rng.uniform(posed.min(0) - 0.1, posed.max(0) + 0.1, (3000, 3)), on_skin])
        far = closed_visible.kernel.far_outside(posed, points, margin, COLUMN_M)
        near = within_reach(points, posed, skin.faces, reach=margin)
        exact = ~near & ~mesh_inside(points, posed, skin.faces, closed=True)  # the numpy ray count
        assert np.array_equal(far, exact)
        assert far.mean() > 0.3 and (~far).mean() > 0.3  # both answers given often


@pytest.mark.parametrize("body", ["visible", "closed_visible"])
def test_the_kernel_pushes_as_the_reference(request, body, skirt_frames):
    _kernel_or_skip()
    visible = request.getfixturevalue(body)
    motion, skirt, frames = skirt_frames
    posed = PosedSkin.of(visible, motion)
    mean = mean_operator(skirt.faces, len(skirt.vertices))
    ref = _push_frames(
        frames, lambda p: posed.distance(p, slice(None), SETTINGS.margin), mean, SETTINGS, None
    )
    got, report = push_out(frames.astype(np.float32), motion, skirt.faces, body=posed, settings=SETTINGS)
    assert ref[1].max() > 0.02  # the skirt starts inside the body
    assert np.abs(got - ref[0]).max() < 1e-5
    assert report.inside_before == pytest.approx(ref[1].mean()) and report.inside_after == pytest.approx(
        ref[2].mean()
    )
    one, _ = push_out(
        frames[3:4].astype(np.float32),
        motion.slice(3, 4),
        skirt.faces,
        body=PosedSkin.of(visible, motion.slice(3, 4)),
        settings=SETTINGS,
    )
    assert np.array_equal(one[0], got[3])  # a frame alone (a stream's) as in the batch


def test_the_kernel_reports_the_cloth_inside_after_its_limit_as_the_reference(closed_visible, skirt_frames):
    """The kernel measures the frames its strain limit moved again itself (only the vertices that
    moved): its report is the reference's measure of what comes out."""
    _kernel_or_skip()
    motion, skirt, frames = skirt_frames
    posed, f32 = PosedSkin.of(closed_visible, motion), frames.astype(np.float32)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices.astype(np.float64))
    strict = replace(SETTINGS, max_strain=1.0, stretch_slack=0.0)  # no edge stretched: the limit acts
    out, report = push_out(f32, motion, skirt.faces, body=posed, settings=strict, limits=limits)
    unlimited, _ = push_out(f32, motion, skirt.faces, body=posed, settings=strict)
    assert not np.array_equal(out, unlimited)  # the limit moved some frames
    d, _ = posed.distance(out.astype(np.float64), slice(None), SETTINGS.margin)
    after = (d < -SETTINGS.depth).mean(1)
    assert report.inside_after == pytest.approx(after.mean())
    assert report.worst_after == pytest.approx(after.max())


def test_a_vertex_deep_inside_is_pushed_out_and_a_far_one_left(closed_visible):
    """Two triangles: one on a thigh's axis (8 cm inside, no skin within the margin: the broad
    phase must not take it for outside), one 30 cm in front of the chest."""
    motion = synthesize("walk", 0.1, seed=1).slice(0, 1)
    a, b = DEFAULT_BODY.pose_motion(motion)
    thigh = next(i for i, c in enumerate(DEFAULT_BODY.capsules) if c.name.endswith("thigh"))
    centre = 0.5 * (a[0, thigh] + b[0, thigh])
    chest = b[0].max(0) * np.array([0.0, 0.85, 0.0]) + np.array([0.0, 0.0, 0.3])
    offsets = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0]])
    points = np.concatenate([centre + offsets, chest + offsets])[None]
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    skin = closed_visible.collider.body
    posed_mesh = skin.pose(motion.global_rotations, motion.joint_positions)[0]
    assert mesh_signed_distance(points[0, :3], posed_mesh, skin.faces).max() < -0.05
    out, report = push_out(
        points.astype(np.float32), motion, faces, body=PosedSkin.of(closed_visible, motion), settings=SETTINGS
    )
    assert report.inside_before == pytest.approx(0.5) and report.inside_after == 0.0
    assert mesh_signed_distance(out[0, :3].astype(np.float64), posed_mesh, skin.faces).min() > 0.0
    assert np.array_equal(out[0, 3:], points[0, 3:].astype(np.float32))


@pytest.mark.slow  # the winding number of 27 frames: 20-25 s
def test_the_cloth_ends_outside_the_visible_mesh(visible, skirt_frames):
    motion, skirt, frames = skirt_frames
    f32 = frames.astype(np.float32)
    on_skin, report = push_out(
        f32, motion, skirt.faces, body=PosedSkin.of(visible, motion), settings=SETTINGS
    )
    on_capsules, _ = push_out(f32, motion, skirt.faces, body=DEFAULT_BODY, settings=SETTINGS)
    # the skirt starts in the bulges (the report: the collider's figure, within a point of the winding
    # number's: this mesh is a union of overlapping capsule surfaces, whose inside no nearest face tells)
    before = _inside(visible, motion, frames).mean()
    assert before > 0.01 and report.inside_before == pytest.approx(before, abs=0.01)
    # the capsules' push leaves the bulges in the cloth; the skin's takes nearly all of them out (what
    # stays is where the capsule surfaces overlap)
    assert _inside(visible, motion, on_capsules).mean() > 0.004
    assert _inside(visible, motion, on_skin).mean() < 0.3 * _inside(visible, motion, on_capsules).mean()


def test_a_crowd_of_two_bodies_pushes_each_as_alone(visible, skirt_frames):
    from hrr_garment.native import load_kernel

    if load_kernel() is None:
        pytest.skip("no C compiler")
    motion, skirt, frames = skirt_frames
    slimmer = VisibleCollider.of(DEFAULT_BODY, BulgingMannequin(0.02).skinned())
    which = np.arange(motion.num_frames) % 2
    crowd = PosedSkin.of_frames((visible, slimmer), which, motion)
    together, _ = push_out(frames.astype(np.float32), motion, skirt.faces, body=crowd, settings=SETTINGS)
    for k, body in enumerate((visible, slimmer)):
        alone, _ = push_out(
            frames.astype(np.float32), motion, skirt.faces, body=PosedSkin.of(body, motion), settings=SETTINGS
        )
        assert np.array_equal(together[which == k], alone[which == k])


def test_the_run_settings_choose_the_body():
    from hrr_garment.inference.run_settings import RunSettings

    with pytest.raises(ValueError, match="push_body"):
        RunSettings(push_body="skin")
    assert RunSettings(push_body="visible", push="subspace").push == "subspace"  # it measures the skin too
    settings = RunSettings(push_body="capsules")
    assert settings.push_body == "capsules" and RunSettings().push_body is None


def test_the_animator_pushes_out_of_the_characters_own_mesh(animator, visible):
    """A character whose body.json carries its own mesh (the bulging body): by default the push-out
    measures that mesh (its report counts the cloth inside it), with push_body="capsules" the
    capsules; on the mannequin, with no mesh, the two are one run. Offline and a crowd agree."""
    from dataclasses import replace

    from hrr_garment.body.mannequin import mannequin_record
    from hrr_garment.body.mesh_record import BodyMesh

    skin = BulgingMannequin(0.05).skinned()
    record = replace(
        mannequin_record(), mesh=BodyMesh.of(skin.vertices, skin.faces, skin.rest_positions, skin.weights)
    )
    motion = synthesize("walk", 0.6, seed=2)
    on_mesh = animator.animate(motion, body=record, causal=True)
    on_capsules = animator.animate(motion, body=record, causal=True, push_body="capsules")
    assert on_mesh.settings["push_body"] == "visible" and on_capsules.settings["push_body"] == "capsules"
    assert not np.array_equal(on_mesh.vertices, on_capsules.vertices)
    plain = [animator.animate(motion, push_body=b).vertices for b in ("visible", "capsules")]
    assert np.array_equal(*plain)
    crowd = animator.crowd()
    crowd.set_body("hero", record)
    for frame in range(3):
        out = crowd.push_motions({"hero": motion.slice(frame, frame + 1)})
        assert np.abs(out[0] - on_mesh.vertices[frame]).max() <= 1e-4
    # the strain limit measures the garment as it rests on the character (kept clear of its mesh: not
    # the template), on the mannequin the template itself
    from hrr_garment.inference.frame_path import FramePath
    from hrr_garment.inference.run_settings import RunSettings

    run = animator.resolve(RunSettings(body=record))
    rest = animator.bundle.template.vertices.astype(np.float64) + run.body.offset
    limits, edges = FramePath(animator, run).push_limits, animator.edge_limits.edges
    assert np.abs(run.body.offset).max() > 1e-3 and limits is not animator.edge_limits
    assert np.allclose(limits.rest_length, np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=-1))
    assert FramePath(animator, animator.resolve(RunSettings())).push_limits is animator.edge_limits


def test_the_torch_stage_on_the_visible_mesh_pushes_as_the_kernel(closed_visible, skirt_frames):
    """The step's push-out stage (a GPU crowd's, the ONNX graph's) with the collider's graph in place
    of the capsules moves the cloth as the package's push-out against the posed skin does, its
    follow and strain limit included (float32 against the kernel); a subspace push is refused."""
    import dataclasses

    import torch

    from hrr_garment.inference.torch_push_out import PushOutStage
    from hrr_garment.models.skin_collider_graph import SkinColliderGraph

    motion, skirt, frames = skirt_frames
    frames = frames.astype(np.float32)
    settings = dataclasses.replace(SETTINGS, follow=4)
    mean = mean_operator(skirt.faces, len(skirt.vertices))
    limits = EdgeLimits.of(skirt.faces, skirt.vertices.astype(np.float64), mean)
    theirs, _ = push_out(
        frames,
        motion,
        skirt.faces,
        body=PosedSkin.of(closed_visible, motion),
        settings=settings,
        mean=mean,
        limits=limits,
        report=False,
    )
    body = DEFAULT_BODY
    stage = PushOutStage(
        (*body.ends, body.radii),
        mean,
        limits=limits,
        settings=settings,
        skin=SkinColliderGraph(closed_visible.collider),
    )
    with torch.no_grad():
        ours = stage(
            torch.from_numpy(frames),
            torch.from_numpy(motion.global_rotations).float(),
            torch.from_numpy(motion.joint_positions).float(),
        ).numpy()
    assert np.abs(theirs - frames).max() > 0.01  # the push moved the cloth a centimetre ...
    assert np.abs(ours - theirs).max() < 1e-5  # ... and the stage moved it the same (0.1 um measured)
    hulled = PushOutStage.of_visible(closed_visible, mean, limits=limits, settings=settings)
    with torch.no_grad():  # with the hulls, as the export has them: the same
        again = hulled(
            torch.from_numpy(frames),
            torch.from_numpy(motion.global_rotations).float(),
            torch.from_numpy(motion.joint_positions).float(),
        ).numpy()
    assert np.abs(again - theirs).max() < 1e-5
    with pytest.raises(ValueError, match="subspace"):
        PushOutStage(
            (*body.ends, body.radii),
            mean,
            limits=limits,
            settings=dataclasses.replace(settings, subspace=object()),
            skin=stage.skin,
        )


def test_the_graphs_hulls_are_the_kernels_and_bound_a_wrong_inside(closed_visible, monkeypatch):
    """The hulls' radii in torch are the package's (VisibleCollider.skinned) in every pose; beyond
    the margin of every hull the stage takes the hulls' distance, as the package's push-out does, so
    a point the collider calls inside there (between the thighs, across the gap from the nearest
    skin, on a real body) is not pushed."""
    from hrr_garment.inference.torch_push_out import PushOutStage
    from hrr_garment.models.skin_collider_graph import SkinColliderGraph

    motion = synthesize("dance", 0.5, seed=2)
    rot, pos = motion.global_rotations, motion.joint_positions
    a, b = DEFAULT_BODY.pose(rot, pos)
    radii = closed_visible.skinned(rot, pos, capsules=(a, b))[3]
    graph = SkinColliderGraph(closed_visible.collider, torch.float64)
    hulls = SkinHulls(closed_visible.envelope).double()
    moves = graph.moves(torch.from_numpy(rot), torch.from_numpy(pos))
    ours = hulls(
        graph.pose(*moves), torch.from_numpy(a), torch.from_numpy(b), torch.from_numpy(DEFAULT_BODY.radii)
    )
    assert (radii > DEFAULT_BODY.radii + 0.005).any()  # the bulges grow the thighs' hulls ...
    assert np.abs(ours.numpy() - radii).max() < 1e-9  # ... as the package grows them

    skirt = squeezed_skirt(motion, 1.0, on_body=True)[0]
    mean = mean_operator(skirt.faces, len(skirt.vertices))
    limits = EdgeLimits.of(skirt.faces, skirt.vertices.astype(np.float64), mean)
    stage = PushOutStage.of_visible(closed_visible, mean, limits=limits, settings=SETTINGS)
    # one frame about the pelvis, as the stage measures: the hulls' ends and radii packed (1, C, 7)
    frame_rot, frame_pos = torch.from_numpy(rot[:1]).float(), torch.from_numpy(pos[:1]).float()
    centre = frame_pos[:, :1]
    ends = torch.from_numpy(np.concatenate([a[:1], b[:1]], -1)).float() - centre.repeat(1, 1, 2)
    hull = torch.cat([ends, torch.from_numpy(radii[:1, :, None]).float()], -1)
    rot_moves, trans = stage.skin.moves(frame_rot, frame_pos)
    wrong = lambda p, character, a, b, surface=None: (torch.full(p.shape[:1], -0.05), torch.zeros_like(p))  # noqa: E731
    monkeypatch.setattr(stage.skin, "query_rows", wrong)  # the collider calls every point inside
    for offset, inside in (([0.0, 0.0, 0.0], True), ([0.0, 0.0, 3.0], False)):  # the pelvis; 3 m before it
        point = torch.tensor([[offset]])
        d, _ = stage.distance(point, rot_moves, trans - centre, hull)
        assert (float(d) < 0) == inside  # the collider's answer near the body, the hulls' far from it


def test_a_crowd_of_two_bodies_limits_each_against_its_own_rest(animator):
    """A crowd of a character whose garment rests clear of its mesh and one on the model's own body:
    one push for both (the strain limit's rest chosen per character), each character's cloth as in
    a crowd of its body alone; the limits made once for the crowd's bodies."""
    from dataclasses import replace

    from hrr_garment.body.mannequin import mannequin_record
    from hrr_garment.body.mesh_record import BodyMesh

    skin = BulgingMannequin(0.05).skinned()
    record = replace(
        mannequin_record(), mesh=BodyMesh.of(skin.vertices, skin.faces, skin.rest_positions, skin.weights)
    )
    dance = synthesize("dance", 0.3, seed=5)
    mixed, alone = animator.crowd(push_body="capsules"), animator.crowd(push_body="capsules")
    mixed.set_body("hero", record)
    alone.set_body("hero", record)
    plain = animator.crowd(push_body="capsules")
    for frame in range(3):
        pose = dance.slice(frame, frame + 1)
        both = mixed.push_motions({"hero": pose, "npc": pose})
        assert np.abs(both[0] - alone.push_motions({"hero": pose})[0]).max() <= 1e-5
        assert np.abs(both[1] - plain.push_motions({"npc": pose})[0]).max() <= 1e-5
    bodies = mixed._stacked[1]
    assert bodies.which is not None and len(bodies._push_limits) == 1  # made once, kept for the crowd
    (limits,) = [made for _, made in bodies._push_limits.values()]
    assert limits.body_of_frame is not None and limits.rest_length.shape[0] == 2
    assert not np.allclose(limits.rest_length[0], limits.rest_length[1])  # the two garments' own rests
