"""The crowd as one torch step (a GPU's path), run on the CPU: each character as the native crowd
gives it, with either decoder; state per key; what it refuses."""

import numpy as np
import pytest

from hrr_garment.motion.poses import motion_to_poses
from hrr_garment.motion.synth import synthesize
from tests.conftest import with_drawn_sampler


@pytest.mark.parametrize("decoder, push", [("full", "mesh"), ("fast", "mesh"), ("fast", "subspace")])
def test_the_device_crowd_equals_the_native_crowd(animator, decoder, push):
    clips = [synthesize("walk_curve", 1.0, seed=1), synthesize("spin", 1.0, seed=2)]
    poses = [motion_to_poses(c) for c in clips]
    native = animator.crowd(mode="regression", decoder=decoder, device="native", push=push)
    device = animator.crowd(mode="regression", decoder=decoder, device="cpu", push=push)
    mesh = animator.crowd(mode="regression", decoder=decoder, device="native")
    worst, moved = 0.0, 0.0
    for t in range(16):
        keys = ["a", "b"] if t >= 5 else ["a"]  # b joins at frame 5
        rotations = np.stack([poses[i][0][t - (5 if k == "b" else 0)] for i, k in enumerate(keys)])
        roots = np.stack(
            [poses[i][1][t - (5 if k == "b" else 0)] + [2.0 * i, 0, 0] for i, k in enumerate(keys)]
        )
        ours, theirs = device.push(rotations, roots, keys), native.push(rotations, roots, keys)
        assert ours.shape == theirs.shape == (len(keys), animator.bundle.template.num_vertices, 3)
        worst = max(worst, float(np.abs(ours - theirs).max()))
        moved = max(moved, float(np.abs(theirs - mesh.push(rotations, roots, keys)).max()))
    assert worst < 1e-4, f"{worst * 1000:.3f} mm from the native crowd"
    assert (moved > 1e-3) == (push == "subspace"), f"the subspace push moved the cloth {moved * 1000:.3f} mm"
    device.leave("a")
    assert device.characters == ["b"]
    with pytest.raises(KeyError, match="no character 'a'"):
        device.leave("a")


def test_the_device_crowds_draw_is_the_native_crowds_for_each_seed(animator):
    """The sample mode as one torch step: each character drawn from the run's seed or its own
    (set_seed before it joins) as the native crowd draws it; a joined character's seed is refused."""
    drawing = with_drawn_sampler(animator)
    rotations, roots = motion_to_poses(synthesize("walk_curve", 1.0, seed=1))
    crowds = [drawing.crowd(mode="sample", seed=5, device=device) for device in ("native", "cpu")]
    for crowd in crowds:
        crowd.set_seed("b", 9)
    worst, apart = 0.0, 0.0
    for t in range(12):
        native, device = (c.push(rotations[[t, t]], roots[[t, t]], ["a", "b"]) for c in crowds)
        worst = max(worst, float(np.abs(native - device).max()))
        apart = max(apart, float(np.abs(native[0] - native[1]).max()))
    assert worst < 1e-4, f"{worst * 1000:.3f} mm from the native crowd"
    assert apart > 100 * worst  # the two seeds drew two cloths from the same poses
    with pytest.raises(ValueError, match="leave it first"):
        crowds[1].set_seed("a", 3)
    with pytest.raises(ValueError, match="seed"):
        crowds[1].set_seed("c", -1)


@pytest.mark.parametrize("mode", ["regression", "sample"])
def test_a_teleport_restarts_a_device_crowds_character_as_the_native_crowd_does(animator, mode):
    """A pelvis 50 m away one frame later is a respawn on a torch device too: the character starts
    afresh there (its draw from its seed again), warned of, the other character carried on, both as
    the native crowd gives them; walking on from there is no teleport."""
    import warnings

    from hrr_garment.errors import TeleportWarning

    model = with_drawn_sampler(animator) if mode == "sample" else animator
    rotations, roots = motion_to_poses(synthesize("walk_curve", 1.0, seed=1))
    crowds = [model.crowd(mode=mode, seed=3, device=device) for device in ("native", "cpu")]
    fresh = model.crowd(mode=mode, seed=3, device="cpu")
    worst, restarted = 0.0, None
    for t in range(14):
        moved = roots[t] + ([50.0, 0.0, 0.0] if t >= 8 else 0.0)  # "b" respawns 50 m away at frame 8
        rot, root = rotations[[t, t]], np.stack([roots[t] + [2.0, 0.0, 0.0], moved])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", TeleportWarning)
            native, device = (c.push(rot, root, ["a", "b"]) for c in crowds)
        jumps = [w for w in caught if issubclass(w.category, TeleportWarning)]
        assert len(jumps) == (2 if t == 8 else 0), [str(w.message) for w in jumps]
        if t == 8:
            assert "'b': the pelvis moved 50 m in one frame" in str(jumps[1].message)
            assert [w.filename for w in jumps] == [__file__] * 2  # each points at the caller's push
            restarted = fresh.push(rot[1:], root[1:], ["b"])
            np.testing.assert_allclose(device[1:], restarted, atol=1e-5)
        worst = max(worst, float(np.abs(native - device).max()))
    assert worst < 1e-4, f"{worst * 1000:.3f} mm from the native crowd"


def test_a_device_crowd_runs_the_regression_or_the_sample_mode_only(animator):
    with pytest.raises(ValueError, match="regression"):
        animator.crowd(mode="hybrid", device="cpu")
    crowd = animator.crowd(mode="regression", device="cpu")
    rotations, roots = motion_to_poses(synthesize("walk", 0.2, seed=0))
    from hrr_garment.errors import InputError

    with pytest.raises(InputError, match="quaternions"):
        crowd.push(rotations[:2, :5], roots[:2])
    with pytest.raises(InputError, match="distinct"):
        crowd.push(rotations[:2], roots[:2], ["x", "x"])


def _dragged_garment(animator, every: int):
    """Three frames of a spin with every ``every``-th garment vertex dragged deep into the body."""
    from hrr_garment.motion.frame import world_vertices

    poses = synthesize("spin", 0.5, seed=3).slice(5, 8)
    rest = np.broadcast_to(animator.bundle.template.vertices, (3, *animator.bundle.template.vertices.shape))
    garment = world_vertices(rest.astype(np.float32), poses)
    garment[:, ::every] = (0.3 * garment[:, ::every] + 0.7 * poses.joint_positions[:, :1]).astype(np.float32)
    return garment, poses


def _pushed(animator, garment, poses, settings, *, torch_stage: bool = False) -> np.ndarray:
    """:func:`push_out` of the garment on the animator's body, or the torch stage's push (a GPU
    crowd's, the ONNX graph's)."""
    import torch

    from hrr_garment.inference.collision import push_out
    from hrr_garment.inference.torch_push_out import PushOutStage

    body = animator.body().body
    if not torch_stage:
        return push_out(
            garment,
            poses,
            animator.bundle.template.faces,
            body=body,
            settings=settings,
            mean=animator.smoothing,
            limits=animator.edge_limits,
            report=False,
        )[0]
    stage = PushOutStage(
        (*body.ends, body.radii), animator.smoothing, limits=animator.edge_limits, settings=settings
    )
    return stage(
        torch.from_numpy(garment),
        torch.from_numpy(poses.global_rotations).float(),
        torch.from_numpy(poses.joint_positions).float(),
    ).numpy()


def test_the_torch_push_out_follows_and_limits_as_the_library_does(animator):
    """Vertices dragged deep into the body, the push-out with its neighbour-follow and strain limit:
    the torch stage (a GPU crowd's, the ONNX graph's) equals :func:`push_out` (float32 against float64)."""
    import dataclasses

    from hrr_garment.inference.collision import PUSH_OUT

    garment, poses = _dragged_garment(animator, 7)
    settings = dataclasses.replace(PUSH_OUT, follow=6)
    ours = _pushed(animator, garment, poses, settings, torch_stage=True)
    theirs = _pushed(animator, garment, poses, settings)
    plain = _pushed(animator, garment, poses, PUSH_OUT)
    assert np.abs(theirs - plain).max() > 1e-3  # the follow moved the cloth ...
    assert np.abs(ours - theirs).max() < 2e-5  # ... and the torch stage moved it the same


@pytest.mark.parametrize("reach, every", [(0, 7), (3, 41)])
def test_the_torch_strain_limit_near_the_tears_limits_as_over_every_edge(animator, monkeypatch, reach, every):
    """The torch stage's strain limit measures the edges within a few rings of a tear; where a
    correction moves a vertex beyond them (many tears, no ring about them), it passes over every
    edge again: either way the cloth is limited as the library limits it. Tears everywhere (every
    7th vertex dragged into the body) or in places (every 41st)."""
    import dataclasses

    from hrr_garment.inference import torch_strain_limit
    from hrr_garment.inference.collision import PUSH_OUT

    monkeypatch.setattr(torch_strain_limit, "LIMIT_REACH", reach)
    again, near = [], []  # whether the passes over every edge ran; the vertices near the tears
    measured = []  # the colours measured by each call of the passes near the tears
    stage_class = torch_strain_limit.StrainLimitStage
    passes, near_of, project = stage_class._passes, stage_class._near, stage_class._project

    def counted(self, p, limit, lists, start=0, near=None):
        again.append(not isinstance(start, int) and int(start) == 0)
        if near is None:
            return passes(self, p, limit, lists, start)
        calls = []
        with monkeypatch.context() as patch:
            patch.setattr(stage_class, "_project", staticmethod(lambda *a: calls.append(1) or project(*a)))
            out = passes(self, p, limit, lists, start, near)
        measured.append((len(calls), bool(out[1]), self.colours))
        return out

    monkeypatch.setattr(stage_class, "_passes", counted)
    monkeypatch.setattr(stage_class, "_near", lambda self, over: near.append(near_of(self, over)) or near[-1])
    garment, poses = _dragged_garment(animator, every)
    limited = _pushed(animator, garment, poses, PUSH_OUT)
    free = _pushed(animator, garment, poses, dataclasses.replace(PUSH_OUT, max_strain=1e6))
    ours = _pushed(animator, garment, poses, PUSH_OUT, torch_stage=True)
    assert np.abs(limited - free).max() > 1e-3  # the limit acted ...
    assert np.abs(ours - limited).max() < 2e-5  # ... and the torch stage limited alike
    assert any(again) == (reach == 0)  # the passes over every edge ran where a correction strayed
    # the passes near the tears stop after the first that strays: with no rings about the tears, the
    # second here (the first moved the ends of the over-long edges alone, all near), not sixty
    for count, strayed, colours in measured:
        assert strayed == (reach == 0) and (count == 2 * colours if strayed else count >= colours)
    if reach:
        assert 0 < float(near[0].float().mean()) < 0.6  # near the tears: a part of the cloth
