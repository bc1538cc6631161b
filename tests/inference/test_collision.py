"""Push-out (hrr_garment.inference.collision): vertices leave the body without spikes, and a push
that would tear the cloth is undone."""

import numpy as np

from hrr_garment.motion.frame import from_body_frame, to_body_frame
from hrr_garment.motion.synth import synthesize
from tests.conftest import squeezed_skirt


def test_push_out_moves_vertices_outside_without_spikes():
    from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.inference.collision import push_out
    from hrr_garment.sim.quality import edge_strain

    skirt = make_garment("skirt", 300)
    motion = synthesize("idle", 0.2, seed=0)
    rest = from_body_frame(
        to_body_frame(np.repeat(skirt.vertices[None], motion.num_frames, 0).astype(np.float64), motion),
        motion,
    )
    squeezed = rest.copy()
    centre = np.array([0.0, 0.0, 0.0])
    centre[[0, 2]] = rest[0, :, [0, 2]].mean(1)
    squeezed[..., [0, 2]] = centre[[0, 2]] + 0.85 * (
        rest[..., [0, 2]] - centre[[0, 2]]
    )  # 15 % narrower: into the hips
    pushed, report = push_out(squeezed.astype(np.float32), motion, skirt.faces)
    assert report.inside_before > 0.05 and report.inside_after == 0.0
    a, b = DEFAULT_BODY.pose_motion(motion)
    d, _, _ = capsule_signed_distance(pushed[0].astype(np.float64), a[0], b[0], DEFAULT_BODY.radii)
    assert d.min() > -1e-6
    edges = skirt.edges()
    # no spikes: edges end at most 35 % longer than in the unsqueezed skirt
    assert (
        edge_strain(pushed, skirt.vertices, edges).max()
        <= edge_strain(rest, skirt.vertices, edges).max() + 0.35
    )
    # the push spreads over the 4 rings around the vertices it needs to move, and nowhere else
    from hrr_garment.garment.smoothing import mean_operator

    near = capsule_signed_distance(squeezed[0].astype(np.float64), a[0], b[0], DEFAULT_BODY.radii)[0] < 0.002
    adjacency, ring = mean_operator(skirt.faces, len(skirt.vertices)), near.copy()
    for _ in range(4):
        ring |= (adjacency @ ring.astype(np.float64)) > 0
    moved = np.abs(pushed[0] - squeezed[0].astype(np.float32)).max(1) > 0
    assert moved[~near].any() and not moved[~ring].any()


def test_a_push_that_would_tear_the_cloth_is_undone_as_far_as_it_tears():
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.inference.edge_limits import EdgeLimits
    from hrr_garment.inference.strain_limit import MAX_PUSH_STRAIN, limit_push_strain
    from hrr_garment.sim.quality import edge_strain

    skirt = make_garment("skirt", 300)
    edges = skirt.edges()
    rng = np.random.default_rng(5)
    unpushed = np.repeat(skirt.vertices[None], 3, 0).astype(np.float32)
    unpushed[2] *= np.float32(1.3)  # a frame the decoder stretched 1.3 x everywhere: not the push's doing
    pushed = unpushed.copy()
    moved = rng.choice(skirt.num_vertices, 4, replace=False)
    pushed[1, moved] += np.float32([0.0, 0.0, 0.3])  # four vertices shoved 30 cm across a limb
    pushed[2, moved] += np.float32([0.0, 0.0, 0.002])  # a gentle push on the stretched frame
    limited, torn = limit_push_strain(pushed, unpushed, EdgeLimits.of(skirt.faces, skirt.vertices))
    assert torn.tolist() == [False, True, False]
    assert edge_strain(pushed[1:2], skirt.vertices, edges).max() > 5
    assert edge_strain(limited[1:2], skirt.vertices, edges).max() < MAX_PUSH_STRAIN * 1.1
    assert np.array_equal(limited[0], pushed[0]) and np.array_equal(limited[2], pushed[2])  # nothing to undo
    # only the torn neighbourhood moves: the shoved vertices come back most of the way, most of the
    # skirt keeps its position exactly, and what lies 20 cm (four edges) or more from the shoved
    # vertices moves by millimetres at most
    change = np.linalg.norm(limited[1] - pushed[1], axis=-1)
    far = np.linalg.norm(skirt.vertices[:, None] - skirt.vertices[moved][None], axis=-1).min(1) > 0.2
    assert change[moved].min() > 0.2 and (change == 0).mean() > 0.5 and change[far].max() < 0.01


def test_the_push_out_with_its_limit_is_the_same_without_the_kernel(monkeypatch):
    """push_out with the strain limit: the kernel's path (each frame limited right after its push)
    and the numpy reference (every frame pushed, then limited) agree on the frames and the report."""
    from hrr_garment import native
    from hrr_garment.inference.collision import EdgeLimits, push_out

    if native.load_kernel() is None:
        import pytest

        pytest.skip("no C compiler")
    motion = synthesize("dance", 0.3, seed=4)
    skirt, squeezed = squeezed_skirt(motion, 0.7)  # deep into the hips: the push tears
    squeezed = squeezed.astype(np.float32)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    native_out, native_report = push_out(squeezed, motion, skirt.faces, limits=limits)
    monkeypatch.setattr(native, "load_kernel", lambda *args, **kwargs: None)
    numpy_out, numpy_report = push_out(squeezed, motion, skirt.faces, limits=limits)
    assert np.abs(native_out - squeezed).max() > 0.01 and native_report.inside_before > 0.05
    unlimited, _ = push_out(squeezed, motion, skirt.faces)
    assert np.abs(unlimited - numpy_out).max() > 1e-3  # the limit undid part of the push
    assert np.abs(native_out - numpy_out).max() < 1e-5
    assert np.allclose(
        [native_report.inside_after, native_report.worst_after],
        [numpy_report.inside_after, numpy_report.worst_after],
        atol=0.01,
    )
    # the report's share of frames the limit moved: exactly the frames the unlimited push left different
    repaired = (np.abs(unlimited - numpy_out).max(axis=(1, 2)) > 0).mean()
    assert repaired > 0 and native_report.limited == numpy_report.limited == repaired


def test_the_report_counts_the_frames_the_strain_limit_repaired():
    """Every fourth frame narrowed where the template lies while the dance moves the legs through it
    (the push tears it), the others worn loose on the body (nothing to repair): the report's
    ``limited`` is those frames' share, and 0 without limits."""
    from hrr_garment.inference.collision import EdgeLimits, push_out
    from hrr_garment.inference.strain_limit import limit_push_strain

    motion = synthesize("dance", 0.4, seed=4)
    skirt, squeezed = squeezed_skirt(motion, 0.7)  # where the template lies: the legs pass through it
    _, loose = squeezed_skirt(motion, 1.3, on_body=True)  # wider than the template: clear of the body
    frames = np.where((np.arange(motion.num_frames) % 4 == 0)[:, None, None], squeezed, loose)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    _, report = push_out(frames.astype(np.float32), motion, skirt.faces, limits=limits)
    unlimited, bare = push_out(frames.astype(np.float32), motion, skirt.faces)
    _, torn = limit_push_strain(unlimited, frames.astype(np.float32), limits)  # the tears the push left
    assert torn.tolist() == (np.arange(motion.num_frames) % 4 == 0).tolist()
    assert report.limited == torn.mean() and bare.limited == 0.0


def test_a_limb_through_the_cloth_is_let_go_of_rather_than_torn():
    """A sheet pierced by the left forearm (T-pose, far from the torso): pushed out of the forearm, its
    vertices inside part to either side and tear it; with ``release_limbs`` the push-out lets go of
    the forearm on that frame instead (the cloth left as it came, through the limb, as the simulator
    leaves cloth where a capture's arms pass through the body), while a frame whose sheet only
    grazes the forearm is pushed as before; the numpy reference, the kernel and the torch stage
    agree."""
    import dataclasses

    from hrr_garment import native
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.inference.collision import PUSH_OUT, EdgeLimits, push_out
    from hrr_garment.inference.limb_release import limb_capsules
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.skeleton import CANONICAL, REST_PELVIS_HEIGHT

    pose = Motion(
        np.broadcast_to(np.eye(3), (2, 22, 3, 3)).copy(),
        np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (2, 1)),
        30.0,
        skeleton=CANONICAL,
    )
    forearm = [c.name for c in DEFAULT_BODY.capsules].index("l_forearm")
    assert forearm in limb_capsules() and len(limb_capsules()) == 10
    a, b = DEFAULT_BODY.pose_motion(pose)
    mid, axis = (a[0, forearm] + b[0, forearm]) / 2, b[0, forearm] - a[0, forearm]
    assert abs(axis[0]) > 0.9 * np.linalg.norm(axis)  # the T-pose's forearm lies along x
    # a 21 x 21 sheet at 1 cm across the forearm's middle (its plane x = const), and the same sheet
    # moved up by the forearm's radius less 1 mm: a graze
    u, w = np.meshgrid(np.linspace(-0.1, 0.1, 21), np.linspace(-0.1, 0.1, 21), indexing="ij")
    sheet = mid + np.stack([np.zeros(u.size), u.ravel(), w.ravel()], 1)
    graze = sheet + [0.0, DEFAULT_BODY.radii[forearm] + 0.101 - 0.001, 0.0]
    quads = np.arange(21 * 21).reshape(21, 21)[:-1, :-1].ravel()
    faces = np.concatenate(
        [np.stack([quads, quads + 21, quads + 1], 1), np.stack([quads + 1, quads + 21, quads + 22], 1)]
    )
    frames = np.stack([sheet, graze]).astype(np.float32)
    limits = EdgeLimits.of(faces, sheet)
    release = dataclasses.replace(PUSH_OUT, release_limbs=True)
    torn, torn_report = push_out(frames, pose, faces, limits=limits)  # the default holds every capsule
    let_go, report = push_out(frames, pose, faces, limits=limits, settings=release)
    assert torn_report.limited == 0.5 and report.limited == 0.0  # the pierced frame tore, and now does not
    assert np.array_equal(let_go[0], frames[0])  # let go of: the sheet as it came
    assert report.inside_after > 0.0  # ... and honestly reported: the forearm's inside it
    assert np.array_equal(let_go[1], torn[1]) and np.abs(let_go[1] - frames[1]).max() > 1e-3  # grazed: pushed
    # the step's torch stage (a GPU crowd's, the ONNX graph's) lets go of it alike
    import torch

    from hrr_garment.inference.collision import mean_operator
    from hrr_garment.inference.torch_push_out import PushOutStage

    stage = PushOutStage(
        (*DEFAULT_BODY.ends, DEFAULT_BODY.radii),
        mean_operator(faces, len(sheet)),
        limits=limits,
        settings=release,
    )
    with torch.no_grad():
        ours = stage(
            torch.from_numpy(frames),
            torch.from_numpy(pose.global_rotations).float(),
            torch.from_numpy(pose.joint_positions).float(),
        ).numpy()
    assert np.abs(ours - let_go).max() < 1e-5
    if native.load_kernel() is not None:
        import unittest.mock

        with unittest.mock.patch.object(native, "load_kernel", lambda *args, **kwargs: None):
            reference, reference_report = push_out(frames, pose, faces, limits=limits, settings=release)
        assert np.abs(reference - let_go).max() < 1e-5 and reference_report.limited == report.limited


def test_frames_resting_on_different_bodies_are_limited_against_their_own_rest(monkeypatch):
    """A garment carried onto a body rests in its own shape (here 1.45 x wider: every edge about its
    axis longer than the template's). Limits made for that rest are the template's with its edge and
    1-ring lengths; a crowd's frames on two bodies, pushed in one call, are limited each against its
    body's rest as if pushed alone, in the kernel and in numpy alike; and the template's lengths take
    the wide garment's own long edges for tears that its own do not."""
    import dataclasses

    import pytest

    from hrr_garment import native
    from hrr_garment.inference.collision import PUSH_OUT, EdgeLimits, push_out

    motion = synthesize("dance", 0.3, seed=4)
    skirt, squeezed = squeezed_skirt(motion, 0.7)  # deep into the hips: the push tears
    wide = skirt.vertices.astype(np.float64).copy()
    centre = wide[:, [0, 2]].mean(0)
    wide[:, [0, 2]] = centre + 1.45 * (wide[:, [0, 2]] - centre)
    template = EdgeLimits.of(skirt.faces, skirt.vertices)
    on_wide = template.on_bodies(wide)
    own = EdgeLimits.of(skirt.faces, wide)
    assert np.allclose(on_wide.rest_length, own.rest_length) and np.array_equal(on_wide.edges, template.edges)
    assert np.allclose(on_wide.ring_length, own.ring_length) and on_wide.body_of_frame is None
    which = np.arange(motion.num_frames) % 2  # even frames on the template's body, odd on the wide one
    frames = squeezed.astype(np.float32)
    both = template.on_bodies(np.stack([skirt.vertices, wide]), which)
    with pytest.raises(ValueError, match="body_of_frame"):
        template.on_bodies(np.stack([skirt.vertices, wide]))
    assert np.array_equal(both.frame_rest_length(len(which))[1], on_wide.rest_length)

    def pushed(limits_of_frames, kernel=True, chunk=PUSH_OUT.chunk):
        if not kernel:
            monkeypatch.setattr(native, "load_kernel", lambda *args, **kwargs: None)
        settings = dataclasses.replace(PUSH_OUT, chunk=chunk)
        out = push_out(frames, motion, skirt.faces, limits=limits_of_frames, settings=settings, report=False)[
            0
        ]
        monkeypatch.undo()
        return out

    mixed = pushed(both)
    alone = {0: pushed(template.on_bodies(skirt.vertices)), 1: pushed(on_wide)}
    for body in (0, 1):
        rows = which == body
        assert np.array_equal(mixed[rows], alone[body][rows])
    assert np.abs(alone[0][which == 1] - alone[1][which == 1]).max() > 1e-3  # the rest matters
    assert np.array_equal(pushed(both, chunk=3), mixed)  # 3 frames at a time (odd: the rows shift)
    if native.load_kernel() is not None:
        assert np.abs(pushed(both, kernel=False) - mixed).max() < 1e-5
    # the wide garment at its own rest, pushed 2 cm sideways at one vertex a frame: no tear against its
    # own lengths; against the template's its stretched edges (1.45 x) are past the 1.5 x limit less
    # the push's 10 % slack, and the push is taken for a tear
    from hrr_garment.inference.strain_limit import limit_push_strain

    rest = np.repeat(wide[None], 4, 0)
    nudged = rest.copy()
    nudged[np.arange(4), [10, 50, 90, 130], 0] += 0.02
    assert not limit_push_strain(nudged, rest, on_wide)[1].any()
    assert limit_push_strain(nudged, rest, template)[1].all()
    # the strain limit alone on the two bodies' frames: each row as on its body alone, kernel and numpy
    rests = np.where(which[:, None, None] == 1, wide[None], skirt.vertices[None].astype(np.float64))
    nudged = rests.copy()
    nudged[:, 10, 0] += 0.03
    got, torn = limit_push_strain(nudged, rests, both)
    for body, alone_limits in ((0, template.on_bodies(skirt.vertices)), (1, on_wide)):
        rows = which == body
        theirs, their_torn = limit_push_strain(nudged[rows], rests[rows], alone_limits)
        assert np.array_equal(got[rows], theirs) and np.array_equal(torn[rows], their_torn)
    monkeypatch.setattr(native, "load_kernel", lambda *args, **kwargs: None)
    reference, reference_torn = limit_push_strain(nudged, rests, both)
    assert np.array_equal(reference_torn, torn) and np.abs(reference - got).max() < 1e-8
    assert torn.any()
