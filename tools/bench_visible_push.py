"""The push-out against the mesh the viewer sees, beside the push-out against the capsules, timed in
the same run (in turn, the median of the rounds): milliseconds a character of a 64-character step
(64 frames pushed at once, each frame its own character's pose: ``PosedSkin.of_frames`` and
``push_out``, the path a crowd's step takes with its characters' meshes; frames in parallel on every
core), wall-clock and the process's CPU time (every core's, so that a machine of N free cores takes
about CPU / N), their ratio (and the visible mesh's without its broad phase, the hulls' cull alone),
and the cloth inside the visible mesh before and after each (the fraction of vertices more than 5 mm
inside, mean and worst frame, on 8 frames spread over the clip: the exact reference takes seconds a
frame). Prints; asserts nothing.

The cloth is an ``hrr-animate`` output (``--animation out.h5``: a trained model's frames, on the
body it names with ``--body``), or by default the dress at rest on an anny body carried by the body
frame through a real clip: no swing, so the legs stride through the skirt and the bodice sits
where the garment was placed (a harder case than a trained model's cloth, and no model needed).

    python tools/bench_visible_push.py ../shared/data/mocap/cmu/02_01.bvh --frames 256
    python tools/bench_visible_push.py walk.bvh --animation out.h5 --body hero.json

The report (the default) measures the frames the strain limit moved again: against the capsules
in numpy, against the skin in the kernel; ``--no-report`` times the push alone, as a stream or a
crowd's step runs it. ``--threads`` sets the kernels' threads (default: PyTorch's). ``--device
cuda`` also times the exported step's push-out (the torch stage an ONNX graph holds: the visible
mesh's collider graph within its hulls, and the capsules' for the ratio) on that torch device, its
inputs already there as a GPU crowd's decoded frames are, each step synchronised, and counts the
vertices it leaves more than 1 mm from the package's push; ``--onnx`` times the same stages
exported to ONNX as a step is (minutes for the visible mesh's) and run by onnxruntime on the CPU,
as an engine runs the step's push-out.

    python tools/bench_visible_push.py 02_01.bvh --frames 64 --no-report --device cpu --onnx
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import cpu_description

DEPTH_M = 0.005  # the push-out report's depth: inside counts past 5 mm
MEASURED = 8  # frames the cloth inside is measured on, evenly spread (the exact reference: seconds each)
APART_M = 0.001  # the torch stage's push and the package's differ where farther apart than this
STEP = 64  # characters a step (the figure: a 64-character step)


def cloth_frames(args, record, motion):
    """(T, V, 3) float32 world frames and the faces: the animation's, or the dress carried."""
    if args.animation:
        from hrr_garment.data.animation_file import read_animation_h5

        animation = read_animation_h5(args.animation)
        return animation.vertices[: motion.num_frames].astype(np.float32), animation.faces
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.garment.dressing import dress
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.motion.frame import world_vertices

    template = make_garment("dress", args.vertices)
    dressed = dress("bench", record, template, made_for=DEFAULT_BODY)[0]
    local = np.repeat((template.vertices + dressed.offset(template))[None], motion.num_frames, 0)
    return world_vertices(local, motion), template.faces


def timed(runs: dict, repeats: int) -> tuple[dict, dict, dict]:
    """The median wall-clock and CPU seconds of ``repeats`` runs of each of ``runs`` and each one's
    last result: the runs taken in turn, ``repeats`` rounds (on a shared machine a load that comes
    and goes falls on every run alike)."""
    wall: dict = {name: [] for name in runs}
    cpu: dict = {name: [] for name in runs}
    out: dict = {}
    for _ in range(repeats):
        for name, run in runs.items():
            t0, c0 = time.perf_counter(), time.process_time()
            out[name] = run()
            wall[name].append(time.perf_counter() - t0)
            cpu[name].append(time.process_time() - c0)
    median = lambda x: {name: float(np.median(t)) for name, t in x.items()}  # noqa: E731
    return median(wall), median(cpu), out


def torch_runs(stages: dict, frames: np.ndarray, motion, cuts: list, device: str) -> dict:
    """Each torch stage (name: ``PushOutStage``) pushing the steps in order on ``device``, its
    inputs moved there first (a GPU crowd decodes its frames there), synchronised at the end."""
    import torch

    where = torch.device(device)
    inputs = [
        tuple(
            torch.from_numpy(np.ascontiguousarray(x[cut])).float().to(where)
            for x in (frames, motion.global_rotations, motion.joint_positions)
        )
        for cut in cuts
    ]

    def stepped(stage):
        stage = stage.to(where)

        def run():
            with torch.no_grad():
                out = torch.cat([stage(*step) for step in inputs])
            if where.type == "cuda":
                torch.cuda.synchronize(where)
            return out

        run()  # the first call allocates and (on a GPU) loads its kernels
        return run

    return {name: stepped(stage) for name, stage in stages.items()}


def onnx_runs(stages: dict, frames: np.ndarray, motion, cuts: list) -> dict:
    """Each torch stage exported to ONNX (as ``hrr-export-model`` exports a step: torch's exporter,
    then one pass of its optimiser) and run by onnxruntime on the CPU, the steps in order."""
    import tempfile
    from pathlib import Path

    import onnxruntime
    import torch

    from hrr_garment.export.graph_export import export_graph
    from hrr_garment.export.onnx_model import OPSET

    names = ["vertices", "rotations", "positions"]
    feeds = [
        {
            k: np.ascontiguousarray(x[cut]).astype(np.float32)
            for k, x in zip(names, (frames, *motion_arrays(motion)))
        }
        for cut in cuts
    ]
    example = tuple(torch.from_numpy(x[:2].copy()) for x in feeds[0].values())
    folder = Path(tempfile.mkdtemp())
    runs = {}
    for name, stage in stages.items():
        characters = torch.export.Dim("characters", min=1, max=4096)
        t0 = time.perf_counter()
        program = export_graph(
            stage.eval(),
            example,
            input_names=names,
            output_names=["pushed"],
            dynamic_shapes=tuple({0: characters} for _ in names),
            opset=OPSET,
            strict_first=True,  # a push-out's loops
        )
        path = folder / f"{len(runs)}.onnx"
        program.save(str(path))
        print(f"{name}: exported in {time.perf_counter() - t0:.0f} s")
        session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])

        def run(session=session):
            return np.concatenate([session.run(None, feed)[0] for feed in feeds])

        run()  # the first run allocates
        runs[name] = run
    return runs


def motion_arrays(motion) -> tuple[np.ndarray, np.ndarray]:
    return motion.global_rotations, motion.joint_positions


def arguments() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("motion", help="a clip (BVH, glTF, npz)")
    p.add_argument("--animation", help="an hrr-animate output (.h5) of that clip, on --body")
    p.add_argument("--body", help="body.json (default: the average anny body)")
    p.add_argument(
        "--frames", type=int, default=256, help="frames of the clip pushed, in whole steps of 64 characters"
    )
    p.add_argument("--vertices", type=int, default=4156, help="the carried dress's vertices")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", type=int, help="the kernels' threads (default: PyTorch's)")
    p.add_argument("--device", help="also time the torch stage's push-out on this device (cpu, cuda)")
    p.add_argument(
        "--onnx",
        action="store_true",
        help="also time the torch stages exported to ONNX, in onnxruntime (CPU)",
    )
    p.add_argument(
        "--no-report",
        action="store_true",
        help="push without the report, as a stream or a crowd's step does (no frame measured again)",
    )
    return p.parse_args()


def main() -> None:
    args = arguments()
    if args.threads:
        import torch

        torch.set_num_threads(args.threads)
    from hrr_garment.body.body_file import read_body, record_of
    from hrr_garment.body.parametric import BodyShape, parametric_body
    from hrr_garment.body.retarget import motion_on_body
    from hrr_garment.body.skinned_body import visible_body
    from hrr_garment.inference.collision import PushOutSettings, mean_operator, push_out
    from hrr_garment.inference.edge_limits import EdgeLimits
    from hrr_garment.inference.visible_push import PosedSkin, VisibleCollider
    from hrr_garment.motion.io import load_motion
    from hrr_garment.native import default_threads

    record = read_body(args.body) if args.body else record_of(parametric_body(BodyShape()))
    skin = visible_body(record)
    if skin is None:
        raise SystemExit("the body has no visible mesh (the mannequin's is its capsules)")
    motion = motion_on_body(load_motion(args.motion), record)
    # whole steps of STEP characters (a clip shorter than one: one step of all its frames)
    steps = max(1, min(args.frames, motion.num_frames) // STEP)
    motion = motion.slice(0, min(steps * STEP, motion.num_frames))
    frames, faces = cloth_frames(args, record, motion)
    t0 = time.perf_counter()
    visible = VisibleCollider.of(record.body, skin)
    built = time.perf_counter() - t0
    settings = PushOutSettings(depth=DEPTH_M)
    mean = mean_operator(faces, frames.shape[1])
    limits = EdgeLimits.of(faces, frames[0].astype(np.float64))
    # the same collider with the broad phase off (as if its mesh were open): the hulls' cull alone
    hulls_only = VisibleCollider(visible.body, visible.envelope, visible.collider)
    hulls_only.__dict__["closed"] = False  # the cached property, set before it is first read
    cuts = [slice(k * STEP, (k + 1) * STEP) for k in range(steps)]

    def stepped(body):
        """Each step posed (``body(poses)``: what push_out takes) and pushed, the steps in order."""

        def run():
            pushed = [
                push_out(
                    frames[cut],
                    motion.slice(cut.start, cut.stop),
                    faces,
                    body=body(motion.slice(cut.start, cut.stop)),
                    settings=settings,
                    mean=mean,
                    limits=limits,
                    report=not args.no_report,
                )[0]
                for cut in cuts
            ]
            return np.concatenate(pushed)

        return run

    run = {
        "capsules": stepped(lambda poses: record.body),
        "visible, hulls only": stepped(lambda poses: PosedSkin.of(hulls_only, poses)),
        "visible": stepped(lambda poses: PosedSkin.of(visible, poses)),
    }
    if args.device or args.onnx:
        from hrr_garment.inference.torch_push_out import PushOutStage

        body = record.body
        stages = {
            "capsules": PushOutStage((*body.ends, body.radii), mean, limits=limits, settings=settings),
            "visible": PushOutStage.of_visible(visible, mean, limits=limits, settings=settings),
        }
        if args.device:
            named = {f"torch {kind} ({args.device})": stage for kind, stage in stages.items()}
            run.update(torch_runs(named, frames, motion, cuts, args.device))
        if args.onnx:
            run.update(
                onnx_runs(
                    {f"onnxruntime {kind}": stage for kind, stage in stages.items()}, frames, motion, cuts
                )
            )
    print(f"{cpu_description()}; {default_threads()} threads; collider built in {built:.1f} s")
    print(
        f"{frames.shape[1]} vertices, {len(frames)} frames of {args.motion}: {len(cuts)} step(s) of "
        f"{len(frames) // len(cuts)} characters"
    )
    seconds, cpu, results = timed(run, args.repeats)
    measured = lambda t: PosedSkin.of(visible, motion.slice(t, t + 1))  # noqa: E731
    report(seconds, cpu, results, measured, frames, device=args.device)


def report(seconds: dict, cpu: dict, results: dict, measured, frames: np.ndarray, *, device) -> None:
    """Prints each run's time a character, the cloth inside the visible mesh (``measured(t)``: the
    skin posed at frame t; on ``MEASURED`` frames) before and after it, and the ratios."""
    sample = np.linspace(0, len(frames) - 1, min(MEASURED, len(frames))).round().astype(int)
    poses = [measured(t) for t in sample]

    def inside(cloth: np.ndarray) -> np.ndarray:
        """Each sampled frame's share of ``cloth`` (T, V, 3) more than DEPTH_M inside the skin."""
        return np.array(
            [
                (pose.distance(cloth[t : t + 1].astype(np.float64), slice(None), 0.0)[0] < -DEPTH_M).mean()
                for t, pose in zip(sample, poses)
            ]
        )

    before = inside(frames)
    package = results["visible"]
    for name, out in results.items():
        out = out if isinstance(out, np.ndarray) else out.float().cpu().numpy()
        apart = ""
        if name.startswith(("torch visible", "onnxruntime visible")):
            far = np.linalg.norm(out - package, axis=-1) > APART_M
            apart = f"; apart from the package's push: {far.sum(1).mean():.2f} vertices a frame"
        after = inside(out)
        moved = np.abs(out - frames).max(-1) > 0
        print(
            f"{name}: {1e3 * seconds[name] / len(frames):.3f} ms a character (CPU "
            f"{1e3 * cpu[name] / len(frames):.3f} ms); inside the visible "
            f"mesh before {100 * before.mean():.2f} % (worst {100 * before.max():.2f} %), after "
            f"{100 * after.mean():.2f} % (worst {100 * after.max():.2f} %); vertices moved "
            f"{100 * moved.mean():.1f} %{apart}"
        )
    print(
        f"visible / capsules: {seconds['visible'] / seconds['capsules']:.2f} x (hulls only "
        f"{seconds['visible, hulls only'] / seconds['capsules']:.2f} x)"
    )
    if device:
        graph, capsules = (seconds[f"torch {kind} ({device})"] for kind in ("visible", "capsules"))
        print(
            f"torch visible / torch capsules: {graph / capsules:.2f} x; torch visible / package "
            f"visible: {graph / seconds['visible']:.2f} x"
        )
    if "onnxruntime visible" in seconds:
        graph, capsules = seconds["onnxruntime visible"], seconds["onnxruntime capsules"]
        print(
            f"onnxruntime visible / onnxruntime capsules: {graph / capsules:.2f} x; onnxruntime visible / "
            f"package visible: {graph / seconds['visible']:.2f} x"
        )


if __name__ == "__main__":
    main()
