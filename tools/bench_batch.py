"""Benchmark: batched cloth simulation (hrr_garment.sim.batch) against batch size, on one device.

Each point simulates a batch of N walks (different seeds, one length) of the same garment in one
newton model, each in its own world, and prints one JSON line: the batch size, simulated frames
per second over the whole batch (lead-in included; solver stepping only, from the batch's own
timing, so scene building and the first substeps' kernel loading are left out), the wall time
including the scene's building, and how far the batch's first sequence lies from the same
sequence simulated alone (the largest vertex difference over its frames, mm). A final line gives each size's
frames per second over batch 1's, and batch 1 against one sequence simulated alone (ClothScene, the unbatched
path).

    python tools/bench_batch.py --device cpu --max-batch 8 --vertices 300 --seconds 1
    python tools/bench_batch.py --device cuda:0 --max-batch 256 --vertices 4000 --seconds 4 --schedule 15x1

Sizes are 1, 2, 4, ... up to --max-batch. Every size runs in this one process, after a warm-up,
so the ratios compare like with like; a GPU's numbers belong to that GPU.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from dataclasses import replace

import numpy as np

from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.batch import BatchItem, simulate_batch
from hrr_garment.sim.simulator import SimResult, SimSettings, simulate_garment


def run_point(items: list[BatchItem], config: SimSettings, alone: np.ndarray) -> dict:
    """One batch size's numbers; ``alone``: the first item's frames simulated alone."""
    t0 = time.perf_counter()
    results = simulate_batch(items, config)
    wall = time.perf_counter() - t0
    kept = [r for r in results if isinstance(r, SimResult)]
    frames = sum(r.simulated_frames for r in kept)
    stepping = sum(r.step_seconds for r in kept)
    return {
        "batch": len(items),
        "exploded": len(items) - len(kept),
        "frames": frames,
        "frames_per_s": round(frames / stepping, 2),
        "ms_per_batch_frame": round(1000 * stepping / max(r.simulated_frames for r in kept), 2),
        "wall_s": round(wall, 2),
        "first_vs_alone_max_mm": round(1000 * float(np.abs(results[0].vertices - alone).max()), 4)
        if isinstance(results[0], SimResult)
        else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="auto", help="warp device: auto, cpu, cuda:0")
    parser.add_argument(
        "--max-batch", type=int, default=8, help="the largest batch (sizes 1, 2, 4, ... up to it)"
    )
    parser.add_argument("--garment", default="dress")
    parser.add_argument("--vertices", type=int, default=300)
    parser.add_argument(
        "--seconds", type=float, default=1.0, help="each clip's length (a 1.3 s lead-in precedes it)"
    )
    parser.add_argument(
        "--schedule", default="10x3", help="substeps x iterations (real-quick: 15x1, real-full: 25x1)"
    )
    args = parser.parse_args()
    substeps, iterations = (int(x) for x in args.schedule.lower().split("x"))
    config = SimSettings(device=args.device, substeps=substeps, iterations=iterations, retries=0)
    garment = make_garment(args.garment, args.vertices)
    sizes = [1]
    while sizes[-1] * 2 <= args.max_batch:
        sizes.append(sizes[-1] * 2)
    items = [
        BatchItem(garment, synthesize("walk", args.seconds, seed=k), DEFAULT_BODY) for k in range(sizes[-1])
    ]
    print(
        json.dumps(
            {
                "machine": platform.processor() or platform.machine(),
                "python": platform.python_version(),
                "device": args.device,
                "garment": args.garment,
                "vertices": garment.num_vertices,
                "seconds": args.seconds,
                "schedule": args.schedule,
            }
        ),
        flush=True,
    )
    simulate_batch(items[:2], replace(config, settle_s=0.0, blend_s=0.0))  # load the kernels
    alone = simulate_garment(garment, items[0].motion, config)
    alone_point = {
        "batch": "alone",
        "frames_per_s": round(alone.simulated_frames / alone.step_seconds, 2),
        "wall_s": round(alone.seconds, 2),
    }
    print(json.dumps(alone_point), flush=True)
    points = []
    for size in sizes:
        points.append(run_point(items[:size], config, alone.vertices))
        print(json.dumps(points[-1]), flush=True)
    base = points[0]["frames_per_s"]
    print(
        json.dumps(
            {
                "frames_per_s_vs_batch_1": {p["batch"]: round(p["frames_per_s"] / base, 2) for p in points},
                "batch_1_vs_alone": round(base / alone_point["frames_per_s"], 2),
            }
        )
    )


if __name__ == "__main__":
    main()
