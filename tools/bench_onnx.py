"""Benchmark: the ONNX streaming step (hrr-export-model --onnx) on onnxruntime's CPU provider beside
the package's own stream (native kernels), the same model, clip and characters, in one run.

    python tools/bench_onnx.py --model hrr_work/models/dress-real-quick \\
        --motion ../shared/data/mocap/cmu/02_01.bvh
    python tools/bench_onnx.py --model DIR --graph dress.onnx --crowds 1 8 32 --json

For each crowd size N, N characters play the clip, each from its own start frame and in its own
place, one call per frame for all of them (the clip played forth and back, so that no character
jumps): first through the graph (onnxruntime, its state fed
back), then through ``animator.crowd(mode="regression")`` (the path the graph holds: push-out,
decoder and push as the graph was written). Prints each side's median and p99 step after the windows fill, the
per-character-frame cost and the ratio ONNX / package. A graph is exported first unless --graph
gives one (exported from the same model).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def _timed(
    push, rotations: np.ndarray, roots: np.ndarray, starts: np.ndarray, offsets: np.ndarray, steps: int
) -> np.ndarray:
    seconds = []
    cycle = np.r_[np.arange(len(rotations)), np.arange(len(rotations) - 2, 0, -1)]  # forth and back: no jump
    for t in range(steps):
        rows = cycle[(starts + t) % len(cycle)]
        start = time.perf_counter()
        push(rotations[rows], roots[rows] + offsets)
        seconds.append(time.perf_counter() - start)
    return 1000.0 * np.array(seconds[15:])  # after the first windows fill


def main() -> None:
    from hrr_garment.export.onnx_model import OnnxStream, export_onnx
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.io import load_motion
    from hrr_garment.motion.poses import motion_to_poses

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", required=True)
    p.add_argument("--motion", type=Path, required=True, help="the clip the characters play")
    p.add_argument(
        "--graph", type=Path, default=None, help="an exported graph of --model (default: export one)"
    )
    p.add_argument("--crowds", type=int, nargs="+", default=[1, 8, 32])
    p.add_argument("--steps", type=int, default=100, help="frames pushed per crowd and side")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    animator = Animator.load(args.model)
    graph = args.graph
    if graph is None:
        graph = Path(tempfile.mkdtemp()) / "step.onnx"
        export_onnx(animator, graph)
    rotations, roots = motion_to_poses(load_motion(args.motion))
    # the package runs what the graph holds: its mode, push-out, decoder and push
    settings = OnnxStream(graph).settings
    rows = []
    for n in args.crowds:
        starts = np.arange(n) * 7 % len(rotations)
        offsets = np.stack([np.arange(n) * 1.5, np.zeros(n), np.zeros(n)], 1).astype(np.float32)
        onnx_ms = _timed(OnnxStream(graph).push, rotations, roots, starts, offsets, args.steps)
        crowd = animator.crowd(**settings)
        package_ms = _timed(crowd.push, rotations, roots, starts, offsets, args.steps)
        row = {
            "characters": n,
            "onnx_p50_ms": float(np.median(onnx_ms)),
            "onnx_p99_ms": float(np.percentile(onnx_ms, 99)),
            "package_p50_ms": float(np.median(package_ms)),
            "package_p99_ms": float(np.percentile(package_ms, 99)),
        }
        row["onnx_per_character_us"] = 1000.0 * row["onnx_p50_ms"] / n
        row["ratio_p50"] = row["onnx_p50_ms"] / row["package_p50_ms"]
        rows.append(row)
        if not args.json:
            print(
                f"{n:4d} characters: ONNX p50 {row['onnx_p50_ms']:7.2f} ms p99 {row['onnx_p99_ms']:7.2f} | "
                f"package p50 {row['package_p50_ms']:7.2f} ms p99 {row['package_p99_ms']:7.2f} | ONNX "
                f"{row['onnx_per_character_us']:.0f} us a character, {row['ratio_p50']:.2f} x the package"
            )
    if args.json:
        print(
            json.dumps(
                {
                    "model": args.model,
                    "vertices": int(animator.bundle.template.num_vertices),
                    "push_out": settings["push_out"],
                    "decoder": settings["decoder"],
                    "push": settings["push"],
                    "crowds": rows,
                },
                indent=2,
            )
        )


if __name__ == "__main__":
    main()
