"""Inference: offline and causal engine, streaming, blending, push-out, hrr-animate and out.h5."""

import json
import math

import numpy as np
import pytest

from hrr_garment.inference.blending import Inertializer, blend_windows, window_weights
from hrr_garment.motion.frame import from_body_frame, to_body_frame
from hrr_garment.motion.synth import synthesize


@pytest.fixture(scope="module")
def animator(trained):
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    return Animator.load(root / "model")


@pytest.mark.parametrize("mode", ["hybrid", "regression", "retrieval", "detail", "naive-nn"])
def test_stream_equals_offline_causal(animator, mode):
    motion = synthesize("walk_curve", 1.2, seed=7)
    causal = animator.animate(motion, mode=mode, causal=True)
    stream = animator.stream(mode=mode)
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal.vertices).max() <= 1e-5
    assert len(stream.crowd._characters[0].features) == animator.window  # bounded memory
    stages = {k: np.array(v) for k, v in stream.stage_s.items()}  # per-stage timings cover every push
    assert all(len(v) == motion.num_frames and (v >= 0).all() for v in stages.values())
    assert sum(v.sum() for v in stages.values()) <= np.sum(stream.latency_s) + 1e-9


@pytest.mark.parametrize("mode", ["hybrid", "detail"])  # detail: a fold playhead per character
def test_a_crowd_streamed_together_equals_each_character_streamed_alone(animator, mode):
    """Characters join and leave between frames; each one's frames equal its own offline causal
    animation (which the single stream equals), whatever the others in the same push."""
    clips = {"a": synthesize("walk_curve", 1.0, seed=1), "b": synthesize("spin", 1.0, seed=2),
             "c": synthesize("dance", 1.0, seed=3)}
    alone = {k: animator.animate(m, mode=mode, causal=True).vertices for k, m in clips.items()}
    joins = {"a": 0, "b": 4, "c": 9}  # b joins at frame 4; a leaves after frame 19, c after 24
    leaves = {"a": 20, "b": 30, "c": 25}
    crowd = animator.crowd(mode=mode)
    for frame in range(30):
        present = [k for k in clips if joins[k] <= frame < leaves[k]]
        for k in set(crowd.characters) - set(present):
            crowd.leave(k)
        poses = {k: clips[k].slice(frame - joins[k], frame - joins[k] + 1) for k in present}
        out = crowd.push_motions(poses)
        assert out.shape == (len(present), animator.bundle.template.num_vertices, 3)
        for row, k in enumerate(present):
            assert np.abs(out[row] - alone[k][frame - joins[k]]).max() <= 1e-5, (k, frame)
    assert crowd.characters == ["b"]
    crowd.leave("b")
    with pytest.raises(KeyError, match="no character 'a'"):
        crowd.leave("a")


@pytest.mark.parametrize("form", ["quaternion", "axis-angle", "matrix"])
def test_raw_poses_stream_like_the_same_clip_from_its_file(animator, tmp_path, form):
    """An engine's arrays (local rotations, root) give what the clip saved to a file and loaded gives."""
    from hrr_garment.motion.io import load_motion, save_motion
    from hrr_garment.motion.rotations import matrix_to_axis_angle, matrix_to_quat

    save_motion(synthesize("walk_curve", 1.0, seed=4), tmp_path / "clip.npz")
    motion = load_motion(tmp_path / "clip.npz")
    expected = animator.animate(motion, causal=True).vertices
    local = motion.local_rotations.astype(np.float64)
    rotations = {"quaternion": matrix_to_quat(local)[..., [1, 2, 3, 0]],  # (x, y, z, w), as engines hand them
                 "axis-angle": matrix_to_axis_angle(local), "matrix": local}[form]
    crowd = animator.crowd()
    two = np.stack([rotations, rotations], 1), np.stack([motion.root_translation, motion.root_translation + 3.0], 1)
    for t in range(motion.num_frames):  # two characters: the clip, and the clip 3 m away
        out = crowd.push(two[0][t], two[1][t], keys=["here", "there"])
        assert np.abs(out[0] - expected[t]).max() <= 1e-4 and np.abs(out[1] - 3.0 - expected[t]).max() <= 1e-4
    single = animator.stream()
    assert np.abs(single.push(rotation=rotations[0], root=motion.root_translation[0]) - expected[0]).max() <= 1e-4


def test_a_source_rig_streams_like_its_file(animator, tmp_path):
    """Poses on a rig with another joint order, centimetres and a baked roll per joint (Bandai-
    Namco's kind of rig: no standing rest pose), pushed as the BVH has them, give what animating
    the file gives: the same joint map, retargeting, roll and floor."""
    from hrr_garment.motion.bvh import read_bvh, write_bvh
    from hrr_garment.motion.io import load_motion
    from hrr_garment.motion.rotations import axis_angle_to_matrix, matrix_to_quat
    from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS
    from hrr_garment.motion.stream_rig import StreamRig

    motion = synthesize("dance", 1.0, seed=6)
    roll = axis_angle_to_matrix(np.random.default_rng(0).normal(size=(22, 3)) * 1.5)  # per-joint rig frames
    local = np.empty_like(motion.global_rotations)
    local[:, 0] = motion.global_rotations[:, 0] @ roll[0]
    for j in range(1, 22):
        local[:, j] = roll[PARENTS[j]].T @ motion.local_rotations[:, j].astype(np.float64) @ roll[j]
    offsets = np.stack([roll[PARENTS[j]].T @ CANONICAL.offsets[j] if j else CANONICAL.offsets[j] for j in range(22)])
    order = [0, 3, 6, 9, 12, 15, 13, 16, 18, 20, 14, 17, 19, 21, 1, 4, 7, 10, 2, 5, 8, 11]  # spine first, then limbs
    path = tmp_path / "rig.bvh"
    write_bvh(path, [JOINT_NAMES[j] for j in order], [order.index(PARENTS[j]) if j else -1 for j in order],
              offsets[order], local[:, order], motion.root_translation, 1 / 30, unit_scale=100.0)
    expected = animator.animate(load_motion(path), causal=True).vertices
    clip = read_bvh(path)  # what an engine holds each frame: the rig's local rotations, the root in its units
    rig = StreamRig.from_bvh(path)
    assert rig.unit_scale == pytest.approx(0.01) and rig.calibration.roll is not None
    crowd = animator.crowd(rig=rig)
    quats = matrix_to_quat(clip.local_rotations.astype(np.float64))[..., [1, 2, 3, 0]]
    for t in range(clip.num_frames):
        out = crowd.push(quats[t][None], clip.local_translations[t, :1], keys=["hero"])
        assert np.abs(out[0] - expected[t]).max() <= 1e-4, t


@pytest.mark.parametrize("rotations, roots, phrase", [
    (np.zeros((2, 21, 4)), np.zeros((2, 3)), r"expected \(N, 22, 4\) quaternions"),
    (np.full((1, 22, 3), np.nan), np.zeros((1, 3)), "rotations are not finite"),
    (np.zeros((1, 22, 4)), np.zeros((1, 3)), "not a rotation"),
    (np.tile(np.eye(3) * 2, (1, 22, 1, 1)), np.zeros((1, 3)), "not a rotation"),
    (np.zeros((1, 22, 3)), np.zeros((2, 3)), r"roots have shape \(2, 3\), expected \(1, 3\)"),
    (np.zeros((1, 22, 3)), np.array([[0.0, np.inf, 0.0]]), "root of pose 0 is not finite"),
])
def test_bad_raw_poses_are_refused_clearly(animator, rotations, roots, phrase):
    from hrr_garment.errors import MotionError

    with pytest.raises(MotionError, match=phrase):
        animator.crowd().push(rotations, roots)


def test_a_push_needs_distinct_keys(animator):
    from hrr_garment.errors import InputError

    with pytest.raises(InputError, match="as many distinct keys"):
        animator.crowd().push(np.zeros((2, 22, 3)), np.zeros((2, 3)), keys=["x", "x"])


def test_stream_refuses_an_offline_only_mode(animator):
    with pytest.raises(ValueError, match="direct"):
        animator.stream(mode="direct")


@pytest.mark.parametrize("mode", ["hybrid", "regression", "retrieval", "naive-nn"])
def test_every_mode_animates_every_frame(animator, mode):
    motion = synthesize("spin", 1.0, seed=2)
    anim = animator.animate(motion, mode=mode)
    assert anim.vertices.shape == (motion.num_frames, animator.bundle.template.num_vertices, 3)
    assert np.isfinite(anim.vertices).all() and anim.joints.shape == (motion.num_frames, 22, 3)
    assert 0 <= anim.entropy.min() and anim.entropy.max() <= math.log(animator.bundle.codespace.config.classes) + 1e-5
    if mode == "regression":
        assert anim.mode.sum() == 0 and (anim.source == -1).all()
    if mode in ("retrieval", "naive-nn"):
        assert anim.mode.all() and (anim.source >= 0).all()


def test_excluding_a_sequence_never_retrieves_it(animator):
    anim = animator.animate(synthesize("walk", 1.0, seed=0), mode="retrieval", exclude_sequence=0)
    assert (anim.source[:, 0] != 0).all()


def test_clip_shorter_than_a_window_is_padded(animator):
    anim = animator.animate(synthesize("walk", 0.2, seed=1))  # 6 frames < W = 10
    assert anim.vertices.shape[0] == 6 and np.isfinite(anim.vertices).all()
    assert animator.animate(synthesize("walk", 0.2, seed=1).slice(0, 1)).vertices.shape[0] == 1


def test_blending_keeps_a_constant_and_favours_centres():
    w = window_weights(10)
    assert np.allclose(w, w[::-1]) and w.argmax() in (4, 5) and w.min() > 0
    windows = np.full((7, 10, 3, 2), 2.5, np.float32)
    assert np.allclose(blend_windows(windows, 16), 2.5)
    ramp = np.arange(16, dtype=np.float32)
    windows = np.stack([ramp[i:i + 10] for i in range(7)])[..., None]
    assert np.allclose(blend_windows(windows, 16)[:, 0], ramp)  # consistent windows blend to themselves


def test_from_body_frame_inverts_the_body_frame(rng):
    motion = synthesize("turn_in_place", 1.0, seed=3)
    points = rng.normal(size=(motion.num_frames, 5, 3))
    assert np.allclose(from_body_frame(to_body_frame(points, motion), motion), points, atol=1e-9)


@pytest.mark.parametrize("native", ["1", "0"])
def test_world_vertices_are_the_body_frame_inverse_in_float32(rng, monkeypatch, native):
    """The kernel (and its fallback) rounds what from_body_frame computes in double: within one
    float32 step of it, frame by frame, one frame alone as in a batch."""
    from hrr_garment.motion.frame import world_vertices

    monkeypatch.setenv("HRR_NATIVE", native)
    motion = synthesize("walk_curve", 1.0, seed=4)
    points = rng.normal(size=(motion.num_frames, 300, 3)).astype(np.float32)
    got = world_vertices(points, motion)
    ref = from_body_frame(points, motion)
    assert got.dtype == np.float32 and got.shape == points.shape
    assert np.abs(got - ref).max() <= 2 * np.spacing(np.float32(np.abs(ref).max()))
    assert np.array_equal(world_vertices(points[7:8], motion.slice(7, 8))[0], got[7])


def test_body_frame_follows_the_pelvis_height_and_heading():
    from hrr_garment.motion.rotations import rotation_about_y, yaw_of
    from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT

    motion = synthesize("jump", 1.5, seed=1)  # the pelvis dips and rises
    assert np.ptp(motion.root_translation[:, 1]) > 0.1
    offset = np.array([[0.1, -0.3, 0.2], [-0.2, 0.1, 0.05]])  # carried rigidly with the pelvis heading
    world = motion.root_translation[:, None] + np.einsum("tij,nj->tni", rotation_about_y(yaw_of(motion.global_rotations[:, 0])), offset)
    local = to_body_frame(world, motion)
    assert np.allclose(local, offset + [0.0, REST_PELVIS_HEIGHT, 0.0], atol=1e-9)


def test_inertialization_is_continuous_in_position_and_velocity():
    inert = Inertializer(frames=6)
    out = np.array([inert.step(np.array([0.01 * t if t < 10 else 1.0 + 0.01 * t]), ("a",) if t < 10 else ("b",))[0]
                    for t in range(30)])
    step = np.diff(out)
    assert abs(step[9] - 0.01) < 0.2  # across the 1.0 jump at frame 10 most of the jump is hidden ...
    assert np.abs(np.diff(step)).max() < 6.0 / 6**2  # ... and absorbed with bounded acceleration
    assert np.abs(out[20:] - (1.0 + 0.01 * np.arange(20, 30))).max() < 0.01  # then it follows the new source
    assert np.abs(out[28:] - (1.0 + 0.01 * np.arange(28, 30))).max() < 1e-3


def test_inertialization_of_a_source_that_changes_every_frame_stays_with_the_sources(rng):
    """Causal retrieval can pick another clip for every window: the switches' offsets must decay
    together, not extrapolate the output's own velocity (which ran away, 721 mm on real clips)."""
    inert = Inertializer(frames=6)
    t = np.arange(600)
    truth = np.sin(t / 20.0)
    sources = truth + rng.normal(0.0, 0.3, len(t))  # every frame another source, 0.3 off the truth
    out = np.array([inert.step(np.array([x]), ("clip", i))[0] for i, x in enumerate(sources)])
    assert np.abs(out - truth).max() < 0.75 and np.abs(out - truth)[100:].mean() < 0.2
    assert np.abs(np.diff(out)).mean() < np.abs(np.diff(sources)).mean()  # smoother than the sources


def test_push_out_moves_vertices_outside_without_spikes():
    from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.inference.collision import push_out
    from hrr_garment.sim.quality import edge_strain

    skirt = make_garment("skirt", 300)
    motion = synthesize("idle", 0.2, seed=0)
    rest = from_body_frame(to_body_frame(np.repeat(skirt.vertices[None], motion.num_frames, 0).astype(np.float64), motion), motion)
    squeezed = rest.copy()
    centre = np.array([0.0, 0.0, 0.0])
    centre[[0, 2]] = rest[0, :, [0, 2]].mean(1)
    squeezed[..., [0, 2]] = centre[[0, 2]] + 0.85 * (rest[..., [0, 2]] - centre[[0, 2]])  # 15 % narrower: into the hips
    pushed, report = push_out(squeezed.astype(np.float32), motion, skirt.faces)
    assert report.inside_before > 0.05 and report.inside_after == 0.0
    a, b = DEFAULT_BODY.pose_motion(motion)
    d, _, _ = capsule_signed_distance(pushed[0].astype(np.float64), a[0], b[0], DEFAULT_BODY.radii)
    assert d.min() > -1e-6
    edges = skirt.edges()
    # no spikes: edges end at most 35 % longer than in the unsqueezed skirt
    assert edge_strain(pushed, skirt.vertices, edges).max() <= edge_strain(rest, skirt.vertices, edges).max() + 0.35
    # the push spreads over the 4 rings around the vertices it needs to move, and nowhere else
    from hrr_garment.garment.smoothing import mean_operator

    near = capsule_signed_distance(squeezed[0].astype(np.float64), a[0], b[0], DEFAULT_BODY.radii)[0] < 0.002
    adjacency, ring = mean_operator(skirt.faces, len(skirt.vertices)), near.copy()
    for _ in range(4):
        ring |= (adjacency @ ring.astype(np.float64)) > 0
    moved = np.abs(pushed[0] - squeezed[0].astype(np.float32)).max(1) > 0
    assert moved[~near].any() and not moved[~ring].any()


def test_hrr_animate_writes_out_h5_and_refuses_bad_motion(trained, tmp_path, capsys, monkeypatch):
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.motion.io import save_motion
    from hrr_garment.native import load_kernel

    root, _, _ = trained
    clip = tmp_path / "walk.npz"
    save_motion(synthesize("walk", 1.0, seed=4), clip)
    out = tmp_path / "out.h5"
    assert animate_main([str(clip), "-o", str(out), "--model", str(root / "model")]) == 0
    said = capsys.readouterr().out
    auto = json.loads((root / "model" / "bundle.json").read_text())["auto"]["mode"]  # the default mode runs it
    assert f"mode auto = {auto}" in said
    assert ("database used" if auto in ("residual", "detail") else "retrieval usage") in said
    data = read_animation_h5(out)
    assert data.vertices.shape == (30, 308, 3) and data.faces.dtype == np.int32
    assert data.joints.shape == (30, 22, 3) and data.mode.dtype == np.uint8
    assert data.capsules.shape == (30, len(data.radii), 2, 3)
    attrs = data.attrs
    assert attrs["fps"] == 30 and attrs["units"] == "m" and attrs["up_axis"] == "Y" and attrs["garment"] == "skirt"
    assert attrs["format_version"] == 2 and len(attrs["model_hash"]) == 16
    with np.load(clip) as z:
        arrays = dict(z)
    arrays["root_translation"] = arrays["root_translation"].copy()
    arrays["root_translation"][3] = np.nan
    bad = tmp_path / "nan.npz"
    np.savez(bad, **arrays)
    out2 = tmp_path / "bad.h5"
    assert animate_main([str(bad), "-o", str(out2), "--model", str(root / "model")]) == 2
    assert "nan.npz" in capsys.readouterr().err and not out2.exists()
    assert animate_main([str(clip), "-o", str(out2), "--model", str(tmp_path / "nothing")]) == 2
    assert "nothing" in capsys.readouterr().err and not out2.exists()
    half = [str(clip), "-o", str(out2), "--model", str(root / "model"), "--precision", "bfloat16"]
    lib = load_kernel()
    if lib is not None and lib.hrr_amx_ready():  # bfloat16 decoding runs where AMX is
        assert animate_main(half) == 0
        assert np.abs(read_animation_h5(out2).vertices - data.vertices).mean() <= 1e-3
        out2.unlink()
        monkeypatch.setattr(lib, "hrr_amx_ready", lambda: 0)  # and is refused clearly elsewhere
    assert animate_main(half) == 2
    assert "AMX" in capsys.readouterr().err and not out2.exists()


def test_hrr_animate_explains_bad_models_and_outputs(trained, tmp_path, capsys, mocap_dir):
    import shutil

    from hrr_garment.cli.animate import main as animate_main

    root, _, _ = trained
    clip = mocap_dir / "cmu" / "02_01.bvh"
    model = tmp_path / "model"
    shutil.copytree(root / "model", model)
    cases = [
        ([str(clip), "-o", str(tmp_path / "out.h5"), "--model", str(model), "--garment", "dress"], "animates a skirt, not a dress"),
        ([str(clip), "-o", str(tmp_path / "missing" / "out.h5"), "--model", str(model)], "not a writable directory"),
    ]
    for args, message in cases:
        assert animate_main(args) == 2
        assert message in capsys.readouterr().err
    weights = model / "decoder.safetensors"
    weights.write_bytes(weights.read_bytes()[:50])
    assert animate_main([str(clip), "-o", str(tmp_path / "out.h5"), "--model", str(model)]) == 2
    assert "decoder.safetensors" in capsys.readouterr().err
    unknown = tmp_path / "odd.bvh"
    unknown.write_text(clip.read_text().replace("LeftUpLeg", "Wing").replace("RightUpLeg", "Fin"))
    assert animate_main([str(unknown), "-o", str(tmp_path / "out.h5"), "--model", str(root / "model")]) == 2
    assert "odd.bvh" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.h5")) and not list(tmp_path.glob(".*tmp*"))


def test_native_capsule_distance_equals_numpy(rng):
    from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
    from hrr_garment.native import load_kernel
    from hrr_garment.native.body import capsule_sdf

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    a, b = DEFAULT_BODY.pose_motion(synthesize("run", 0.2, seed=1))
    points = rng.normal(size=(500, 3)) * 0.3 + [0.0, 1.0, 0.0]
    d, n, _ = capsule_signed_distance(points, a[2], b[2], DEFAULT_BODY.radii)
    d2, n2 = capsule_sdf(lib, np.stack([points, points + 0.1]), a[2:4], b[2:4], DEFAULT_BODY.radii)
    assert np.allclose(d, d2[0], atol=1e-12) and np.allclose(n, n2[0], atol=1e-12)
    d3, _, _ = capsule_signed_distance(points + 0.1, a[3], b[3], DEFAULT_BODY.radii)
    assert np.allclose(d3, d2[1], atol=1e-12)  # each frame against its own capsules


def test_game_loop_example_runs_headless(trained, tmp_path, capsys):
    import importlib.util
    from pathlib import Path

    root, _, _ = trained
    spec = importlib.util.spec_from_file_location("game_loop", Path(__file__).parents[1] / "examples" / "game_loop.py")
    game_loop = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(game_loop)
    frames = tmp_path / "frames"
    assert game_loop.main(["--model", str(root / "model"), "--headless", "--seconds", "1", "--frames-dir", str(frames),
                           "--save-every", "8", "--size", "64"]) == 0
    assert sorted(p.name for p in frames.iterdir()) == [f"frame_{t:05d}.png" for t in range(0, 30, 8)]
    assert "crowd.push p50" in capsys.readouterr().out


def test_native_push_out_equals_numpy(rng):
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.inference.collision import _push_frames, mean_operator
    from hrr_garment.native import load_kernel
    from hrr_garment.native.body import push_out_frames

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    skirt = make_garment("skirt", 300)
    motion = synthesize("dance", 0.3, seed=4)
    rest = from_body_frame(to_body_frame(np.repeat(skirt.vertices[None], motion.num_frames, 0).astype(np.float64), motion), motion)
    centre = rest[:, :, [0, 2]].mean(1, keepdims=True)
    squeezed = rest.copy()
    squeezed[..., [0, 2]] = centre + 0.85 * (rest[..., [0, 2]] - centre)  # into the hips
    squeezed += rng.normal(scale=0.004, size=squeezed.shape)
    a, b = DEFAULT_BODY.pose_motion(motion)
    mean = mean_operator(skirt.faces, len(skirt.vertices))
    for rounds in (1, 2):
        ref = _push_frames(squeezed.copy(), a, b, DEFAULT_BODY.radii, mean, 0.002, 4, rounds, 0.005)
        got = push_out_frames(lib, squeezed, a, b, DEFAULT_BODY.radii, mean, 0.002, 4, rounds, 0.005, threads=2)
        assert ref[1].max() > 0.05  # the test squeezes the skirt into the body
        assert np.abs(got[0] - ref[0]).max() < 1e-6
        assert np.allclose(got[1], ref[1]) and np.allclose(got[2], ref[2])
        for t in (0, 4):  # one frame at a time (streaming): the threads share the frame
            one = push_out_frames(lib, squeezed[t:t + 1], a[t:t + 1], b[t:t + 1], DEFAULT_BODY.radii, mean, 0.002, 4,
                                  rounds, 0.005, threads=2)
            assert np.array_equal(one[0][0], got[0][t]) and one[1][0] == got[1][t] and one[2][0] == got[2][t]


def test_bench_inference_reports_every_key(capsys):
    """The benchmark's JSON keeps the keys the issue names (speeds are measured there, not here)."""
    import importlib.util
    import json
    import sys
    from pathlib import Path

    path = Path(__file__).parents[1] / "tools" / "bench_inference.py"
    spec = importlib.util.spec_from_file_location("bench_inference", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    argv = sys.argv
    sys.argv = [str(path), "--vertices", "300", "--database", "300", "--seconds", "1.5", "--pace", "60", "--json"]
    try:
        bench.main()
    finally:
        sys.argv = argv
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in ("vertices", "fps_hybrid", "fps_regression", "fps_retrieval", "fps_detail", "stream_p50_ms", "stream_p99_ms",
                "stream_paced_p50_ms", "stream_paced_p99_ms", "peak_rss_mb"):
        assert report[key] > 0, key
    assert report["stream_p50_ms"] <= report["stream_p99_ms"]
    assert set(report["stream_stage_p50_ms"]) == {"features", "encoder", "decoder", "world", "push_out"}


@pytest.mark.parametrize("damage, phrase", [
    (lambda v: v.__setitem__((3, 5, 0), np.nan), r"non-finite vertices on 1 frame\(s\), first at frame 3"),
    (lambda v: v.__setitem__((2, 0, 1), 7.0), "m from the body at frame 2"),
])
def test_an_absurd_animation_is_refused_and_nothing_is_written(tmp_path, damage, phrase):
    from hrr_garment.errors import InputError
    from hrr_garment.inference.animator import Animation

    motion = synthesize("walk", 0.2, seed=0)
    joints = motion.joint_positions.astype(np.float32)
    vertices = joints[:, :1] + np.zeros((1, 10, 3), np.float32)  # every vertex at the pelvis
    anim = Animation(vertices, np.array([[0, 1, 2]]), 30.0, np.zeros(len(joints), np.uint8), np.zeros(len(joints), np.float32),
                     -np.ones((len(joints), 2), np.int32), joints, "skirt", "hash", "walk")
    anim.check(tmp_path / "ok.h5")  # a plausible one passes
    damage(anim.vertices)
    with pytest.raises(InputError, match=phrase):
        anim.save(tmp_path / "out.h5")
    assert not list(tmp_path.iterdir())


def test_a_push_that_would_tear_the_cloth_is_undone_as_far_as_it_tears():
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.inference.collision import MAX_PUSH_STRAIN, EdgeLimits, limit_push_strain
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
    # only the torn neighbourhood moves: most of the skirt keeps its position exactly, and what lies
    # 15 cm or more from the shoved vertices moves by millimetres at most
    change = np.linalg.norm(limited[1] - pushed[1], axis=-1)
    far = np.linalg.norm(skirt.vertices[:, None] - skirt.vertices[moved][None], axis=-1).min(1) > 0.15
    assert (change == 0).mean() > 0.5 and change[far].max() < 0.005


def test_the_native_strain_limit_matches_the_numpy_reference():
    """The kernel's limits, torn frames and Jacobi passes are the reference's: same edges, weights
    and per-frame stop (the kernel measures only edges whose ends moved: the same result)."""
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.inference.collision import (
        LIMIT_TOLERANCE_M,
        MAX_PUSH_STRAIN,
        OVER_RELAXATION,
        EdgeLimits,
        _limit_frames,
    )
    from hrr_garment.native import load_kernel
    from hrr_garment.native.body import limit_strain

    lib = load_kernel()
    if lib is None:
        pytest.skip("no C compiler")
    skirt = make_garment("skirt", 300)
    limits = EdgeLimits.of(skirt.faces, skirt.vertices)
    rng = np.random.default_rng(2)
    unpushed = np.repeat(skirt.vertices[None], 4, 0).astype(np.float64)
    p = unpushed.copy()
    for t, size in enumerate([0.3, 0.05, 0.0, 0.12]):  # frame 2: nothing over the limit
        p[t, rng.choice(skirt.num_vertices, 5, replace=False)] += rng.normal(size=(5, 3)) * size
    limit = np.repeat(MAX_PUSH_STRAIN * limits.rest_length[None], 4, 0)
    ref = _limit_frames(p.copy(), limit, limits, 60)
    got, torn = limit_strain(lib, p, unpushed, limits.native_arrays, MAX_PUSH_STRAIN, 60, LIMIT_TOLERANCE_M,
                             OVER_RELAXATION, threads=2)
    assert torn.tolist() == [True, True, False, True]
    assert np.abs(got - ref).max() < 1e-8  # metres: float rounding of the same passes
    assert np.array_equal(got[2], p[2]) and np.abs(got - p).max() > 0.01
    one, _ = limit_strain(lib, p[3:], unpushed[3:], limits.native_arrays, MAX_PUSH_STRAIN, 60, LIMIT_TOLERANCE_M,
                          OVER_RELAXATION)
    assert np.array_equal(one[0], got[3])  # a frame's result does not depend on its batch

def test_pinning_the_workers_leaves_the_caller_free(monkeypatch):
    """A stream pins its OpenMP workers, each to one CPU other than the caller's, and leaves the
    calling thread's own affinity as it was (it belongs to the user's program)."""
    import os

    from hrr_garment import native

    lib = native.load_kernel()
    allowed = os.sched_getaffinity(0)
    if lib is None or len(allowed) < 2:
        pytest.skip("needs the kernel and two CPUs")
    monkeypatch.delenv("OMP_PROC_BIND", raising=False)
    monkeypatch.setenv("HRR_PIN_THREADS", "1")
    monkeypatch.setattr(native, "_pinned", {})
    native.pin_workers(2)
    assert os.sched_getaffinity(0) == allowed
    me = os.getpid()

    def affinity(task: str) -> set[int]:
        text = open(f"/proc/{me}/task/{task}/status").read()
        spans = next(line for line in text.splitlines() if line.startswith("Cpus_allowed_list")).split()[1]
        cpus = set()
        for span in spans.split(","):
            lo, _, hi = span.partition("-")
            cpus.update(range(int(lo), int(hi or lo) + 1))
        return cpus

    pinned = [cpus for task in os.listdir(f"/proc/{me}/task") if (cpus := affinity(task)) != allowed]
    assert pinned and all(len(cpus) == 1 and cpus <= allowed for cpus in pinned)


def test_a_bfloat16_crowd_stays_near_the_float32_one(animator):
    """Eight characters (a batch the AMX decoder takes) in bfloat16: the same gate decisions and
    windows, vertices within bfloat16's rounding of the float32 crowd's."""
    from hrr_garment.inference.animator import Animator

    if not animator.decoder.native or not animator.decoder.lib.hrr_amx_ready():
        pytest.skip("no AMX (bfloat16 decoding) on this CPU")
    half = Animator(animator.bundle, precision="bfloat16")
    clips = [synthesize(kind, 1.0, seed=i) for i, kind in enumerate(["walk_curve", "spin", "dance", "idle"] * 2)]
    crowds = [a.crowd(collision=False) for a in (animator, half)]
    error = []
    for t in range(clips[0].num_frames):
        poses = {i: c.slice(t, t + 1) for i, c in enumerate(clips)}
        exact, rounded = (crowd.push_motions(poses) for crowd in crowds)
        error.append(np.linalg.norm(rounded - exact, axis=-1))
    error = np.array(error)
    assert error.mean() <= 2e-4 and error.max() <= 2e-3  # metres
