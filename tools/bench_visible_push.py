"""The push-out against the mesh the viewer sees, beside the push-out against the capsules, timed in
the same run (in turn, the median of the rounds): milliseconds a character of a 64-character step
(64 frames pushed at once, each frame its own character's pose: ``PosedSkin.of_frames`` and
``push_out``, the path a crowd's step takes with its characters' meshes; frames in parallel on every
core), wall-clock and the process's CPU time (every core's, so that a machine of N free cores takes
about CPU / N), their ratio (and the visible mesh's without its broad phase, the hulls' cull alone),
and the cloth inside the visible mesh before and after each (the fraction of vertices more than 5 mm
inside, mean and worst frame). Prints; asserts nothing.

The cloth is an ``hrr-animate`` output (``--animation out.h5``: a trained model's frames, on the
body it names with ``--body``), or by default the dress at rest on an anny body carried by the body
frame through a real clip: no swing, so the legs stride through the skirt and the bodice sits
where the garment was placed (a harder case than a trained model's cloth, and no model needed).

    python tools/bench_visible_push.py ../shared/data/mocap/cmu/02_01.bvh --frames 256
    python tools/bench_visible_push.py walk.bvh --animation out.h5 --body hero.json

The report (the default) measures the frames the strain limit moved again: against the capsules
in numpy, against the skin in the kernel; ``--no-report`` times the push alone, as a stream or a
crowd's step runs it. ``--threads`` sets the kernels' threads (default: PyTorch's).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import cpu_description

DEPTH_M = 0.005  # the push-out report's depth: inside counts past 5 mm
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
    print(f"{cpu_description()}; {default_threads()} threads; collider built in {built:.1f} s")
    print(
        f"{frames.shape[1]} vertices, {len(frames)} frames of {args.motion}: {len(cuts)} step(s) of "
        f"{len(frames) // len(cuts)} characters"
    )
    seconds, cpu, results = timed(run, args.repeats)
    measured = PosedSkin.of(visible, motion)
    before = (measured.distance(frames.astype(np.float64), slice(None), 0.0)[0] < -DEPTH_M).mean(1)
    for name, out in results.items():
        after = (measured.distance(out.astype(np.float64), slice(None), 0.0)[0] < -DEPTH_M).mean(1)
        moved = np.abs(out - frames).max(-1) > 0
        print(
            f"{name}: {1e3 * seconds[name] / len(frames):.3f} ms a character (CPU "
            f"{1e3 * cpu[name] / len(frames):.3f} ms); inside the visible "
            f"mesh before {100 * before.mean():.2f} % (worst {100 * before.max():.2f} %), after "
            f"{100 * after.mean():.2f} % (worst {100 * after.max():.2f} %); vertices moved "
            f"{100 * moved.mean():.1f} %"
        )
    print(
        f"visible / capsules: {seconds['visible'] / seconds['capsules']:.2f} x (hulls only "
        f"{seconds['visible, hulls only'] / seconds['capsules']:.2f} x)"
    )


if __name__ == "__main__":
    main()
