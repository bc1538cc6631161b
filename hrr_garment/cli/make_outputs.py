"""hrr-make's outputs once the model is trained, each by the command a user would run for it:
the ONNX graph for the character's body (hrr-export-model), the character's own clips with the dress
(hrr-animate --body, hrr-export --character, hrr-preview), and the report (hrr-eval on the held-out
library clips against their truth ensembles, with the streamed step's time). make.json records each
stage's commands."""

from __future__ import annotations

import json
import shlex
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import HRRError
from ..io_utils import atomic_write_text, strict_json
from ..pipeline.make_record import content_key

if TYPE_CHECKING:
    from ..motion.motion import Motion
    from .make_run import MakeRun

STEP_FRAMES = 120  # streamed frames the report times the step on (the first 10 warm it)
SHOWCASE_CLIPS = 2  # held-out library clips played on a character without animations of its own


def _call(main, argv: list[str]) -> str:
    """Run a command's body in-process (its errors raise); the command line it stands for."""
    main([str(a) for a in argv])
    return shlex.join(str(a) for a in argv)


def write_outputs(run: MakeRun) -> None:
    """The ONNX graph, the clips and the report (each skipped when current)."""
    outputs = run.out / "outputs"
    outputs.mkdir(parents=True, exist_ok=True)
    model_key = content_key(["model", run.keys["train"]])
    planned = run.record.plan.get("outputs", run.request.outputs)  # the report dropped without test clips
    for stage, make in (("onnx", _onnx), ("clips", _clips), ("report", _report)):
        if stage in planned:
            make(run, outputs, model_key)


def _character(run: MakeRun) -> Path:
    """What the outputs pose: the character file where it is one, else the body.json written."""
    character = run.request.character
    return run.body_path if character.suffix.lower() == ".json" else character


def _onnx(run: MakeRun, outputs: Path, model_key: str) -> None:
    from .export_model import _main as export_model

    graph = _graph_path(run, outputs)
    if run.record.current("onnx", model_key) and graph.exists():
        return
    with run.progress.stage("onnx") as t:
        argv = ["--model", run.model, "--onnx", "-o", graph, "--body", _character(run)]
        command = _call(export_model, argv + ([] if run.request.progress else ["--quiet"]))
    run.record.finish("onnx", model_key, t.seconds, {"command": "hrr-export-model " + command})


def _graph_path(run: MakeRun, outputs: Path) -> Path:
    """The ONNX graph the onnx stage writes for the character (and the report times)."""
    return outputs / f"{run.request.character.stem}.onnx"


def _showcase(run: MakeRun) -> list[tuple[str, Path]]:
    """The clips the outputs play: the character's own animations, else the first held-out clips."""
    if run.own_motions:
        return [(p.stem, p) for p in run.own_motions]
    from ..data.dataset import GarmentDataset
    from ..data.splits import mirror_source

    ds = GarmentDataset(run.dataset)
    chosen = [n for n in ds.splits.get("test", []) if mirror_source(n) == n][:SHOWCASE_CLIPS]
    return [(name, _motion_file(run, ds, name)) for name in chosen]


def _motion_file(run: MakeRun, ds, name: str) -> Path:
    """A held-out sequence of ``ds`` (the run's dataset) as a motion file hrr-animate reads (its piece
    of the library's clip)."""
    from ..motion.native_file import save_motion

    path = run.out / "motions" / "held_out" / f"{name}.npz"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        save_motion(ds.sequence(name).motion, path)
    return path


def _clips(run: MakeRun, outputs: Path, model_key: str) -> None:
    from .animate import _main as animate
    from .export import _main as export
    from .preview import _main as preview

    clips = _showcase(run)
    key = content_key(["clips", model_key, [name for name, _ in clips]])
    played = [outputs / "clips" / f"{name}.h5" for name, _ in clips]
    if run.record.current("clips", key) and all(p.exists() for p in played):
        return
    character, commands = _character(run), []
    is_glb = character.suffix.lower() in (".glb", ".gltf")
    with run.progress.stage("clips") as t:
        for k, (name, motion) in enumerate(clips):
            played = outputs / "clips" / f"{name}.h5"
            played.parent.mkdir(parents=True, exist_ok=True)
            commands.append(
                "hrr-animate "
                + _call(animate, [motion, "-o", played, "--model", run.model, "--body", character])
            )
            glb = outputs / f"{run.request.character.stem}_{name}.glb"
            extra = ["--character", character] if is_glb else ["--with-body"]
            commands.append("hrr-export " + _call(export, [played, "-o", glb, *extra]))
            if k == 0:
                commands.append("hrr-preview " + _call(preview, [played, "-o", outputs / "preview.png"]))
    run.record.finish("clips", key, t.seconds, {"clips": [n for n, _ in clips], "commands": commands})


def _report(run: MakeRun, outputs: Path, model_key: str) -> None:
    from .eval import _main as evaluate

    folder = outputs / "report"
    if run.record.current("report", model_key) and (folder / "report.json").exists():
        return
    members = run.shares.ensemble
    with run.progress.stage("report") as t:
        argv = ["--model", run.model, "--split", "test", "--modes", "auto", "--no-sweep", "--library", "0"]
        argv += ["--jobs", run.request.jobs] if run.request.jobs else []
        argv += [] if run.request.progress else ["--quiet"]
        command = _call(evaluate, [*argv, "--no-plots", "--ensemble", members, "-o", folder])
        motion = _timed_clip(run)
        step = _step_ms(run, motion)
        graph = _graph_path(run, outputs)
        graph_step = _graph_step_ms(graph, motion) if graph.exists() else None
    summary = _summary(folder / "report.json", step, graph_step)
    atomic_write_text(outputs / "summary.json", strict_json(summary, indent=2))
    run.record.finish("report", model_key, t.seconds, {"command": "hrr-eval " + command, **summary})
    print(
        f"held-out clips: PVE / floor {_number(summary['pve_over_floor'])}, cloth inside the body "
        f"before / after the push-out {_number(summary['inside_before_pct'])} / "
        f"{_number(summary['inside_after_pct'])} %; streamed step {summary['step_ms']:.2f} ms (median)"
        + ("" if graph_step is None else f", its ONNX graph in onnxruntime {graph_step:.2f} ms")
    )


def _number(value) -> str:
    return "n/a" if value is None else f"{value:.3g}"


def _timed_clip(run: MakeRun) -> "Motion":
    """The held-out clip the report times a step on (the dataset's first test sequence)."""
    from ..data.dataset import GarmentDataset

    ds = GarmentDataset(run.dataset)
    return ds.sequence((ds.splits.get("test") or ds.names)[0]).motion


def _median_ms(push, frames: int) -> float:
    """The median milliseconds of ``push(frame)`` over ``frames`` frames, the first 10 warming it."""
    times = []
    for frame in range(frames):
        t0 = time.perf_counter()
        push(frame)
        times.append(time.perf_counter() - t0)
    return float(1000 * np.median(times[10:] or times))


def _step_ms(run: MakeRun, motion: "Motion") -> float:
    """The median time of one streamed frame on the character's body, over the held-out ``motion``."""
    from ..inference.animator import Animator

    animator = Animator.load(run.model)
    stream = animator.stream(body=animator.body(run.body_path))
    return _median_ms(lambda t: stream.push(motion.slice(t, t + 1)), min(STEP_FRAMES, motion.num_frames))


def _graph_step_ms(graph: Path, motion: "Motion") -> float:
    """The same clip's frames through the ONNX graph written for the character, one character in
    onnxruntime (what an engine runs): its median milliseconds a frame."""
    from ..export.onnx_model import OnnxStream
    from ..motion.poses import motion_to_poses

    rotations, roots = motion_to_poses(motion)
    stream = OnnxStream(graph)
    frames = min(STEP_FRAMES, len(rotations))
    return _median_ms(lambda t: stream.push(rotations[t : t + 1], roots[t : t + 1]), frames)


def _summary(report: Path, step_ms: float, graph_step_ms: float | None = None) -> dict:
    """The report's headline numbers for the run's own summary."""
    data = json.loads(report.read_text(encoding="utf-8"))
    try:
        auto = data["modes"]["auto"]
        ensemble, metrics = auto.get("ensemble", {}), auto["metrics"]
    except KeyError as exc:
        raise HRRError(f"{report}: the report lacks {exc}") from None
    return {
        "pve_over_floor": ensemble.get("pve_floor_ratio"),
        "floor_mm": ensemble.get("floor_mm"),
        "pve_mm": metrics.get("pve_mm"),
        "inside_before_pct": metrics.get("inside_visible_before_pct"),
        "inside_after_pct": metrics.get("inside_visible_pct"),
        "push_limited_pct": metrics.get("push_limited_pct"),
        "step_ms": step_ms,
        "onnx_step_ms": graph_step_ms,  # the written graph's step in onnxruntime (None: no graph written)
        "motion_licence": data.get("model", {}).get("motion_licence", {}).get("statement"),
    }
