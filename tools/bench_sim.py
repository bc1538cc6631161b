"""Benchmark: cloth simulation speed and quality against vertex count and substeps.

Each point simulates the dress on the same walk and spin (one process, one core: Warp's CPU kernels
are single-threaded) and prints one JSON line: vertices, substeps x iterations, steady-state
milliseconds per 30-fps frame and frames per second per core (solver stepping only; scene building
and the lead-in's kernel warm-up excluded), and the quality numbers the dataset is held to
(edge strain p99, worst-frame penetration, hem swing). A final line gives the ratios between points.

    python tools/bench_sim.py                       # the default grid (about ten minutes)
    python tools/bench_sim.py --vertices 1000 4000 --schedules 10x3 20x2 --seconds 2

A schedule that explodes (the simulator's own checks) is reported as such, not retried.
"""

from __future__ import annotations

import argparse
import json
import platform

from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.quality import sequence_stats
from hrr_garment.sim.simulator import SimSettings, SimulationExploded, simulate_garment


def run_point(vertices: int, substeps: int, iterations: int, seconds: float, kinds: list[str]) -> dict:
    garment = make_garment("dress", vertices)
    config = SimSettings(substeps=substeps, iterations=iterations, retries=0)
    frames = stepping = 0.0
    worst: dict = {"strain_p99": 0.0, "penetration_max": 0.0}
    swing = {}
    for kind in kinds:
        clip = synthesize(kind, seconds, seed=0)
        try:
            result = simulate_garment(garment, clip, config)
        except SimulationExploded as exc:
            return {
                "vertices": garment.num_vertices,
                "substeps": substeps,
                "iterations": iterations,
                "exploded": str(exc),
            }
        frames += result.simulated_frames
        stepping += result.step_seconds
        stats = sequence_stats(
            result.vertices, garment.vertices, garment.edges(), clip, garment.groups["hem"]
        )
        worst = {k: max(worst[k], stats[k]) for k in worst}
        swing[kind] = round(stats["hem_swing_m"], 4)
    return {
        "vertices": garment.num_vertices,
        "substeps": substeps,
        "iterations": iterations,
        "ms_per_frame": round(1000 * stepping / frames, 1),
        "frames_per_s_per_core": round(frames / stepping, 2),
        "strain_p99": round(worst["strain_p99"], 4),
        "penetration_max_pct": round(100 * worst["penetration_max"], 3),
        "hem_swing_m": swing,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=[1000, 2000, 4000])
    parser.add_argument(
        "--schedules",
        nargs="+",
        default=["5x3", "15x2", "20x2"],
        help="substeps x iterations tried at the largest vertex count (10x3, the default, always)",
    )
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--kinds", nargs="+", default=["walk", "spin"])
    args = parser.parse_args()
    print(
        json.dumps(
            {"machine": platform.processor() or platform.machine(), "python": platform.python_version()}
        )
    )
    simulate_garment(
        make_garment("skirt", 100), synthesize("idle", 0.2), SimSettings(settle_s=0, blend_s=0)
    )  # load kernels
    base = []
    for v in args.vertices:
        base.append(run_point(v, 10, 3, args.seconds, args.kinds))
        print(json.dumps(base[-1]), flush=True)
    top = max(args.vertices)
    at_top = [base[-1]]
    for sched in args.schedules:
        substeps, iterations = (int(x) for x in sched.lower().split("x"))
        if (substeps, iterations) != (10, 3):
            at_top.append(run_point(top, substeps, iterations, args.seconds, args.kinds))
            print(json.dumps(at_top[-1]), flush=True)
    first = base[0]
    ratios = {
        "ms_per_frame_vs_vertices": {
            f"{p['vertices']}v/{first['vertices']}v": round(p["ms_per_frame"] / first["ms_per_frame"], 2)
            for p in base[1:]
            if "ms_per_frame" in p and "ms_per_frame" in first
        },
        "vertex_ratio": {
            f"{p['vertices']}v/{first['vertices']}v": round(p["vertices"] / first["vertices"], 2)
            for p in base[1:]
        },
        "ms_per_frame_vs_10x3": {
            f"{p['substeps']}x{p['iterations']}": round(p["ms_per_frame"] / base[-1]["ms_per_frame"], 2)
            for p in at_top[1:]
            if "ms_per_frame" in p and "ms_per_frame" in base[-1]
        },
    }
    print(json.dumps(ratios))


if __name__ == "__main__":
    main()
