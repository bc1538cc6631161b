"""The streaming step in ONNX (hrr-export-model --onnx): onnxruntime gives what the Python stream
gives, frame by frame and character by character; its push-out equals the library's where the
strain limit works, on the capsules and on a character's own mesh; the example runs with numpy and
onnxruntime alone; bad inputs are refused."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("onnxruntime")
pytest.importorskip("onnxscript")

from hrr_garment.cli.export_model import main as export_model_main  # noqa: E402
from hrr_garment.cli.motion import main as motion_main  # noqa: E402
from hrr_garment.errors import InputError  # noqa: E402
from hrr_garment.motion.poses import motion_to_poses  # noqa: E402
from hrr_garment.motion.synth import synthesize  # noqa: E402
from tests.conftest import with_drawn_sampler  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def exported(trained, tmp_path_factory):
    """The tiny model, its ONNX graph (push-out on) and a clip that turns and swings."""
    from hrr_garment.export.onnx_model import export_onnx
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    animator = Animator.load(root / "model")
    path = tmp_path_factory.mktemp("onnx") / "skirt.onnx"
    written = export_onnx(animator, path)
    return animator, written, synthesize("spin", 2.0, seed=3)


def test_the_graph_streams_each_character_as_the_python_stream_does(exported):
    """Two characters in one batch, each from its own frame of a spinning clip, against a Python
    stream each: within a hundredth of a millimetre (the acceptance bar is 0.1) on every frame."""
    from hrr_garment.export.onnx_model import OnnxStream

    animator, written, clip = exported
    rotations, roots = motion_to_poses(clip)
    starts = np.array([0, 17])
    graph = OnnxStream(written.graph)
    streams = [animator.stream(mode="regression") for _ in starts]
    worst = 0.0
    for t in range(clip.num_frames - starts.max()):
        both = graph.push(
            rotations[starts + t], roots[starts + t] + np.array([[0, 0, 0], [2.0, 0, 0]], np.float32)
        )
        for i, (stream, start) in enumerate(zip(streams, starts)):
            alone = stream.push(rotation=rotations[start + t], root=roots[start + t] + [2.0 * i, 0, 0])
            worst = max(worst, float(np.abs(both[i] - alone).max()))
    assert both.shape == (2, animator.bundle.template.num_vertices, 3)
    assert worst < 1e-5, f"ONNX departs from the Python stream by {worst * 1000:.4f} mm"


def test_the_graphs_push_out_limits_the_strain_as_the_library_does(exported):
    """Vertices dragged into the body, so that the push tears edges and the strain limit works: the
    graph's push-out stage equals :func:`push_out` with its limit (float32 against float64)."""
    import torch

    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.export.onnx_model import stream_step
    from hrr_garment.inference.collision import push_out
    from hrr_garment.inference.frame_path import FramePath
    from hrr_garment.inference.strain_limit import limit_push_strain
    from hrr_garment.motion.frame import world_vertices

    animator, _, clip = exported
    step = stream_step(FramePath(animator, animator.resolve(mode="regression", causal=True)))
    poses = clip.slice(10, 13)
    rest = np.broadcast_to(animator.bundle.template.vertices, (3, *animator.bundle.template.vertices.shape))
    garment = world_vertices(rest.astype(np.float32), poses)
    pelvis = poses.joint_positions[:, :1]
    garment[:, ::7] = (0.3 * garment[:, ::7] + 0.7 * pelvis).astype(
        np.float32
    )  # every 7th vertex deep inside
    ours = step.push_out(
        torch.from_numpy(garment),
        torch.from_numpy(poses.global_rotations).float(),
        torch.from_numpy(poses.joint_positions).float(),
    ).numpy()
    pushed, _ = push_out(
        garment,
        poses,
        animator.bundle.template.faces,
        body=DEFAULT_BODY,
        mean=animator.smoothing,
        report=False,
    )
    _, torn = limit_push_strain(pushed, garment, animator.edge_limits)
    assert torn.all(), "the case must exercise the strain limit"
    theirs, _ = push_out(
        garment,
        poses,
        animator.bundle.template.faces,
        body=DEFAULT_BODY,
        mean=animator.smoothing,
        limits=animator.edge_limits,
        report=False,
    )
    assert np.abs(theirs - pushed).max() > 1e-3  # the limit moved vertices by millimetres ...
    assert np.abs(ours - theirs).max() < 2e-5  # ... and the graph moved them the same


def test_the_graph_pushes_out_of_a_characters_own_mesh_as_the_library_does(exported, tmp_path):
    """A character whose body.json carries its mesh (a mannequin with bulging thighs): the graph's
    push-out measures that mesh through the collider's graph (issue 82) and streams as the Python
    stream does, whose push-out is the kernel's against the posed skin; asked for the capsules, it
    streams otherwise."""
    from dataclasses import replace

    from hrr_garment.body.mannequin import mannequin_record
    from hrr_garment.body.mesh_record import BodyMesh
    from hrr_garment.export.onnx_model import OnnxStream, export_onnx
    from tests.body.limb import BulgingMannequin

    animator, _, _ = exported
    skin = BulgingMannequin(0.05).skinned()
    record = replace(
        mannequin_record(), mesh=BodyMesh.of(skin.vertices, skin.faces, skin.rest_positions, skin.weights)
    )
    written = export_onnx(animator, tmp_path / "hero.onnx", body=record)
    rotations, roots = motion_to_poses(synthesize("walk", 0.6, seed=2))
    graph, stream = OnnxStream(written.graph), animator.stream(mode="regression", body=record)
    assert graph.settings["push_body"] == "visible"  # recorded, for check_onnx's stream
    capsules = animator.stream(mode="regression", body=record, push_body="capsules")
    worst, apart = 0.0, 0.0
    for t in range(len(rotations)):
        ours = graph.push(rotations[t : t + 1], roots[t : t + 1])[0]
        theirs = stream.push(rotation=rotations[t], root=roots[t])
        worst = max(worst, float(np.abs(ours - theirs).max()))
        apart = max(apart, float(np.abs(theirs - capsules.push(rotation=rotations[t], root=roots[t])).max()))
    assert apart > 1e-3  # the mesh pushes the skirt otherwise than the capsules ...
    # ... as the graph, within the acceptance bar: the skin's graph in float32 can take the other of
    # two faces equally near within its rounding, and push a vertex along its normal (0.016 mm seen)
    assert worst < 1e-4, f"ONNX departs from the Python stream by {worst * 1000:.4f} mm"


def test_the_fast_decoders_graph_with_the_subspace_push_streams_as_the_python_stream_does(exported, tmp_path):
    """The graph with the subspace decoder and the push along its components first (hrr-export-model
    --decoder fast --push subspace; its solve in ONNX loops, ONNX having none): smaller, and what the
    Python stream with the same settings gives, where that push moves the cloth."""
    from hrr_garment.export.onnx_model import check_onnx, export_onnx

    animator, full, clip = exported
    clip = clip.slice(0, 20)
    written = export_onnx(animator, tmp_path / "fast.onnx", decoder="fast", push="subspace")
    assert written.graph.stat().st_size < full.graph.stat().st_size
    gap = check_onnx(animator, written.graph, clip)
    rotations, roots = motion_to_poses(clip)
    streams = [animator.stream(mode="regression", decoder="fast", push=push) for push in ("mesh", "subspace")]
    frames = [[s.push(rotation=r, root=x) for r, x in zip(rotations, roots)] for s in streams]
    acted_mm = 1000.0 * np.abs(np.array(frames[0]) - np.array(frames[1])).max()
    assert (
        acted_mm > 0.01
    )  # the subspace push moved this tiny skirt (by little: its cloth keeps off the body) ...
    assert gap["max_mm"] < min(0.01, acted_mm / 10)  # ... and the graph moved it as the stream did


def _example(graph: Path, poses: Path, output: Path, *flags: str) -> np.ndarray:
    """examples/onnx_stream.py run on ``graph`` with hrr_garment and torch made unimportable -> its
    first character's garment frames."""
    blocked = (
        "import runpy, sys\n"
        "for name in ('hrr_garment', 'torch'): sys.modules[name] = None\n"
        f"sys.argv = ['onnx_stream.py', {str(graph)!r}, {str(poses)!r}, '-o', {str(output)!r}, "
        f"'--characters', '2', *{list(flags)!r}]\n"
        f"runpy.run_path({str(ROOT / 'examples' / 'onnx_stream.py')!r}, run_name='__main__')\n"
    )
    done = subprocess.run([sys.executable, "-c", blocked], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return np.load(output)


@pytest.mark.tool
def test_the_example_streams_with_numpy_and_onnxruntime_alone(exported, drawn, tmp_path):
    """examples/onnx_stream.py with hrr_garment and torch made unimportable: its first character's
    garment equals the graph run through the package; a sample mode's graph is fed numpy's white
    noise, the same seed the same cloth, another seed another."""
    from hrr_garment.export.onnx_model import OnnxStream
    from hrr_garment.motion.io import save_motion

    _, written, clip = exported
    save_motion(clip, tmp_path / "spin.npz")
    assert motion_main(["poses", str(tmp_path / "spin.npz"), "-o", str(tmp_path / "spin.poses.npz")]) == 0
    poses = tmp_path / "spin.poses.npz"
    garment = _example(written.graph, poses, tmp_path / "garment.npy")
    rotations, roots = motion_to_poses(clip)
    graph = OnnxStream(written.graph)
    alone = np.stack([graph.push(rotations[t : t + 1], roots[t : t + 1])[0] for t in range(clip.num_frames)])
    assert garment.shape == alone.shape
    assert np.abs(garment - alone).max() < 1e-5
    seeded = [
        _example(drawn[1].graph, poses, tmp_path / f"drawn{seed}.npy", "--seed", seed) for seed in "337"
    ]
    assert seeded[0].shape == alone.shape and np.isfinite(seeded[0]).all()
    assert np.array_equal(seeded[0], seeded[1]) and np.abs(seeded[0] - seeded[2]).max() > 1e-4


def test_poses_round_trip_to_the_motion():
    from hrr_garment.motion.poses import poses_to_motion

    clip = synthesize("dance", 1.0, seed=1)
    rotations, roots = motion_to_poses(clip)
    assert rotations.shape == (clip.num_frames, 22, 4) and roots.dtype == np.float32
    back = poses_to_motion(rotations, roots)
    assert np.abs(back.local_rotations - clip.local_rotations).max() < 1e-5
    assert np.abs(back.joint_positions - clip.joint_positions).max() < 1e-5


def test_bad_requests_are_refused_with_the_reason(tmp_path, capsys):
    from hrr_garment.export.onnx_model import OnnxStream

    assert export_model_main(["--model", str(tmp_path), "-o", str(tmp_path / "x.onnx")]) == 2
    assert "--onnx" in capsys.readouterr().err
    assert export_model_main(["--model", str(tmp_path), "--onnx", "-o", str(tmp_path / "x.txt")]) == 2
    assert ".onnx" in capsys.readouterr().err
    (tmp_path / "junk.onnx").write_bytes(b"not a graph")
    with pytest.raises(InputError, match="junk.onnx.*not an ONNX model"):
        OnnxStream(tmp_path / "junk.onnx")
    assert not (tmp_path / "x.onnx").exists()
    # before any model is read
    for flags in (["--sample-steps", "2"], ["--mode", "sample", "--seed", "-1"], ["--settle", "-1"]):
        assert (
            export_model_main(["--model", str(tmp_path), "--onnx", "-o", str(tmp_path / "x.onnx"), *flags])
            == 2
        )
        assert flags[-2] in capsys.readouterr().err


@pytest.mark.parametrize(
    "flags", [["--push-body", "capsules"], ["--push-body", "visible"], [], ["--settle", "1.5"], ["--quiet"]]
)
def test_the_command_exports_the_run_its_flags_ask(trained, tmp_path, monkeypatch, flags):
    """--push-body (with --decoder and --push) reaches the export: a request for the capsules
    exported the visible mesh's push-out, at 60-280 x the native step's cost. The export's progress
    bar is shown unless --quiet."""
    from hrr_garment.export import onnx_model

    asked = {}

    def recording(animator, path, settings=None, **changes):
        asked.update(changes)
        raise InputError(path, "recorded")  # stop before the export's minute

    monkeypatch.setattr(onnx_model, "export_onnx", recording)
    root, _, _ = trained
    command = ["--model", str(root / "model"), "--onnx", *flags, "-o", str(tmp_path / "x.onnx")]
    assert export_model_main(command) == 2
    assert asked["settle"] == (1.5 if "--settle" in flags else 0.0)
    assert asked["push_body"] == (flags[1] if flags[:1] == ["--push-body"] else None)  # None: the default
    assert asked["push_out"] is True and asked["decoder"] is None and asked["push"] is None
    assert asked["progress"] is ("--quiet" not in flags)


@pytest.fixture(scope="module")
def drawn(exported, tmp_path_factory):
    """The tiny model with a hand-calibrated sampler and its sample mode's graph, without the push-out
    (the graphs above hold it; the sample mode changes what comes before it, and the push-out's trace
    is two thirds of a tiny step's export time)."""
    from hrr_garment.export.onnx_model import export_onnx

    drawing = with_drawn_sampler(exported[0])
    folder = tmp_path_factory.mktemp("drawn")
    return drawing, export_onnx(drawing, folder / "drawn.onnx", mode="sample", push_out=False)


def test_the_sample_modes_graph_draws_what_the_python_stream_draws_from_the_same_seed(
    exported, drawn, tmp_path
):
    """hrr-export-model --mode sample: the graph fed each character's white noise from its seed
    (OnnxStream) gives the Python stream's draw for that seed, character by character in one batch
    (a sampler of untrained weights, calibrated by hand: equality holds for any weights); two seeds
    give two cloths; a sampler that reads the frames drawn before cannot be held."""
    from hrr_garment.export.onnx_model import NOISE, OnnxStream, check_onnx, export_onnx

    animator, _, clip = exported
    drawing, written = drawn
    latent = drawing.bundle.sampler.latent_size
    assert written.noise == (2, latent) and "sample_latents" in written.state
    clip = clip.slice(0, 25)
    rotations, roots = motion_to_poses(clip)
    graph = OnnxStream(written.graph, seeds=[3, 4])
    streams = [drawing.stream(mode="sample", seed=seed, push_out=False) for seed in (3, 4)]
    worst, apart = 0.0, 0.0
    for t in range(clip.num_frames):
        both = graph.push(rotations[[t, t]], roots[[t, t]])
        alone = [s.push(rotation=rotations[t], root=roots[t]) for s in streams]
        worst = max(worst, *(float(np.abs(both[i] - alone[i]).max()) for i in range(2)))
        apart = max(apart, float(np.abs(alone[0] - alone[1]).max()))
    assert worst < 1e-5, f"the sample graph departs from the Python stream by {worst * 1000:.4f} mm"
    assert apart > 100 * max(worst, 1e-7)  # the seeds drew apart, far beyond the paths' gap
    assert check_onnx(drawing, written.graph, clip, seed=3)["max_mm"] < 0.01
    assert NOISE in [i.name for i in graph.session.get_inputs()]
    with pytest.raises(ValueError, match="seeds for"):
        OnnxStream(written.graph, seeds=[1, 2, 3]).push(rotations[:2], roots[:2])
    with pytest.raises(ValueError, match="history"):
        export_onnx(with_drawn_sampler(animator, history=1), tmp_path / "x.onnx", mode="sample")
    with pytest.raises(ValueError, match="swing"):  # the graph runs the swing as predicted
        export_onnx(drawing, tmp_path / "x.onnx", mode="sample", swing=1.3)
    assert not (tmp_path / "x.onnx").exists()


def test_the_graph_with_the_settling_lag_streams_as_the_python_stream_does(exported, tmp_path):
    """hrr-export-model --settle S: the lag's state (``settled``) carried through the graph, a walk
    that stops streamed as the Python stream with the same lag gives it; the graph records it. (No
    push-out: the lag acts before it, and the graphs above hold it.)"""
    from hrr_garment.export.onnx_model import OnnxStream, check_onnx, export_onnx
    from hrr_garment.motion.compose import held_still

    animator, plain, _ = exported
    clip = held_still(synthesize("walk_curve", 1.0, seed=3), 45)
    written = export_onnx(animator, tmp_path / "settled.onnx", settle=1.0, push_out=False)
    assert "settled" in written.state and OnnxStream(written.graph).settings["settle"] == 1.0
    assert OnnxStream(plain.graph).settings["settle"] == 0.0 and "settled" not in plain.state
    assert check_onnx(animator, written.graph, clip)["max_mm"] < 0.01
    rotations, roots = motion_to_poses(clip)
    lagged, unlagged = OnnxStream(written.graph), animator.stream(mode="regression", push_out=False)
    apart = max(
        float(np.abs(lagged.push(r[None], x[None])[0] - unlagged.push(rotation=r, root=x)).max())
        for r, x in zip(rotations, roots)
    )
    assert apart > 1e-3  # the lag acted after the stop
