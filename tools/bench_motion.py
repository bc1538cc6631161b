"""Benchmark: a real BVH clip from file to 124-d features (parse, resample, retarget, features).

Prints one JSON object: the clip, its frames, the median wall time of the full path over several
runs (after one warm-up run that pays for imports), and source frames processed per second.

    python tools/bench_motion.py [--clip PATH] [--repeat N]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from hrr_garment import load_motion, motion_features
from hrr_garment.motion.bvh import read_bvh
from hrr_garment.paths import find_mocap_dir


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=None, help="BVH file (default: shared CMU 131_03.bvh)")
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    clip = args.clip
    if clip is None:
        mocap = find_mocap_dir()
        if mocap is None:
            raise SystemExit("shared/data/mocap not found; pass --clip")
        clip = mocap / "cmu" / "131_03.bvh"
    source_frames = read_bvh(clip).num_frames
    stages = {"parse": [], "load_total": [], "features": [], "total": []}
    for i in range(args.repeat + 1):
        t0 = time.perf_counter()
        read_bvh(clip)
        t1 = time.perf_counter()
        motion = load_motion(clip)
        t2 = time.perf_counter()
        feats = motion_features(motion)
        t3 = time.perf_counter()
        if i == 0:
            continue  # warm-up
        stages["parse"].append(t1 - t0)
        stages["load_total"].append(t2 - t1)
        stages["features"].append(t3 - t2)
        stages["total"].append(t3 - t1)
    med = {k: float(np.median(v)) for k, v in stages.items()}
    print(
        json.dumps(
            {
                "clip": clip.name,
                "source_frames": source_frames,
                "frames_30fps": int(feats.shape[0]),
                "seconds_file_to_features": round(med["total"], 4),
                "seconds_parse_only": round(med["parse"], 4),
                "seconds_load_retarget": round(med["load_total"], 4),
                "seconds_features": round(med["features"], 4),
                "source_frames_per_s": round(source_frames / med["total"], 1),
                "machine": f"{platform.processor() or platform.machine()}, {__import__('os').cpu_count()} "
                f"cores, Python {platform.python_version()}",
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
