"""Benchmark: dataset simulation on Ray with 1 and 2 workers (and the local pool), one run each.

Builds the same small dataset (the quick dress on a few procedural clips) from scratch several
ways in a temporary folder and prints one JSON line per way: simulated frames (lead-in included),
wall seconds of the simulation phase, frames per second, and scaling efficiency against one Ray
worker (frames/s with N workers / (N x frames/s with one)). Kernels are compiled once before
timing. Needs the `sim` and `cluster` extras. Run it on an otherwise idle machine.

    python tools/bench_ray.py                       # 4 clips of 3 s: about 5 minutes on 2 cores
    python tools/bench_ray.py --clips 8 --seconds 4 --workers 1 2 4
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
from pathlib import Path

from hrr_garment.garment.templates import make_garment
from hrr_garment.sim.build import BuildSettings, build_dataset, warm_up
from hrr_garment.sim.plan import plan_sequences
from hrr_garment.sim.preset import load_preset
from hrr_garment.sim.simulator import SimSettings

KINDS = ("walk", "run", "spin", "dance", "side_step", "jump", "hop", "walk_curve")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--clips", type=int, default=4)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--vertices", type=int, default=1000)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    garment = make_garment("dress", args.vertices)
    config = SimSettings.from_dict(load_preset("quick").sim)
    specs = plan_sequences(
        load_preset("quick"), [KINDS[i % len(KINDS)] for i in range(args.clips)], args.seconds
    )
    warm_up(garment, config)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        ways = [("ray", n) for n in args.workers] + [("local", max(args.workers))]
        for executor, jobs in ways:
            out = Path(tmp) / f"{executor}-{jobs}.h5"
            report = build_dataset(
                garment,
                specs,
                config,
                out=out,
                options=BuildSettings(jobs=jobs, preview=None, progress=False, executor=executor),
            )
            s = report.summary
            frames = sum(st.get("simulated_frames", 0) for st in report.stats.values())
            rows.append(
                {
                    "executor": executor,
                    "workers": jobs,
                    "sequences": s["sequences"],
                    "simulated_frames": frames,
                    "wall_s": round(s["sim_wall_s"], 1),
                    "frames_per_s": round(frames / s["sim_wall_s"], 2),
                }
            )
    base = next(
        r["frames_per_s"] for r in rows if r["executor"] == "ray" and r["workers"] == min(args.workers)
    )
    for r in rows:
        r["scaling_efficiency"] = round(r["frames_per_s"] / (base * r["workers"] / min(args.workers)), 3)
        print(json.dumps(r))
    print(
        json.dumps(
            {
                "machine": platform.processor() or platform.machine(),
                "cores": os.cpu_count(),
                "vertices": garment.num_vertices,
                "clips": args.clips,
                "seconds": args.seconds,
            }
        )
    )


if __name__ == "__main__":
    main()
