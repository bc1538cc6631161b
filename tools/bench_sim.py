"""Benchmark: cloth simulation speed and quality against vertex count and substeps.

Each point simulates the dress on the same walk and spin (one process, one core: Warp's CPU kernels
are single-threaded) and prints one JSON line: vertices, substeps x iterations, steady-state
milliseconds per 30-fps frame and frames per second per core (solver stepping only; scene building
and the lead-in's kernel warm-up excluded), and the quality numbers the dataset is held to
(edge strain p99, worst-frame penetration, hem swing). A final line gives the ratios between points.

    python tools/bench_sim.py                       # the full-resolution grid (a few minutes)
    python tools/bench_sim.py --vertices 1000 4000 --substeps 10 --seconds 2
"""

from __future__ import annotations

import argparse
import json
import platform

from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.quality import sequence_stats
from hrr_garment.sim.simulator import SimConfig, simulate_garment


def run_point(vertices: int, substeps: int, iterations: int, seconds: float, kinds: list[str]) -> dict:
    garment = make_garment("dress", vertices)
    config = SimConfig(substeps=substeps, iterations=iterations, retries=0)
    frames = stepping = 0.0
    worst: dict = {"strain_p99": 0.0, "penetration_max": 0.0}
    swing = {}
    for kind in kinds:
        clip = synthesize(kind, seconds, seed=0)
        result = simulate_garment(garment, clip, config)
        frames += result.simulated_frames
        stepping += result.step_seconds
        stats = sequence_stats(result.vertices, garment.vertices, garment.edges(), clip, garment.groups["hem"])
        worst = {k: max(worst[k], stats[k]) for k in worst}
        swing[kind] = round(stats["hem_swing_m"], 4)
    return {"vertices": garment.num_vertices, "substeps": substeps, "iterations": iterations,
            "ms_per_frame": round(1000 * stepping / frames, 1), "frames_per_s_per_core": round(frames / stepping, 2),
            "strain_p99": round(worst["strain_p99"], 4), "penetration_max_pct": round(100 * worst["penetration_max"], 3),
            "hem_swing_m": swing}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=[1000, 2000, 4000])
    parser.add_argument("--substeps", type=int, nargs="+", default=[5, 10, 20], help="varied at the largest vertex count")
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--kinds", nargs="+", default=["walk", "spin"])
    args = parser.parse_args()
    print(json.dumps({"machine": platform.processor() or platform.machine(), "python": platform.python_version()}))
    simulate_garment(make_garment("skirt", 100), synthesize("idle", 0.2), SimConfig(settle_s=0, blend_s=0))  # load kernels
    points = []
    for v in args.vertices:
        points.append(run_point(v, 10, args.iterations, args.seconds, args.kinds))
        print(json.dumps(points[-1]), flush=True)
    top = max(args.vertices)
    for s in args.substeps:
        if s != 10:
            points.append(run_point(top, s, args.iterations, args.seconds, args.kinds))
            print(json.dumps(points[-1]), flush=True)
    base = [p for p in points if p["substeps"] == 10]
    first = base[0]
    ratios = {
        "ms_per_frame_vs_vertices": {f"{p['vertices']}v/{first['vertices']}v": round(p["ms_per_frame"] / first["ms_per_frame"], 2)
                                     for p in base[1:]},
        "vertex_ratio": {f"{p['vertices']}v/{first['vertices']}v": round(p["vertices"] / first["vertices"], 2) for p in base[1:]},
    }
    at_top = {p["substeps"]: p["ms_per_frame"] for p in points if p["vertices"] == base[-1]["vertices"]}
    ratios["ms_per_frame_vs_substeps"] = {f"{s}/10": round(ms / at_top[10], 2) for s, ms in sorted(at_top.items()) if s != 10}
    print(json.dumps(ratios))


if __name__ == "__main__":
    main()
