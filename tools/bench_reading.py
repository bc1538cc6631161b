"""Benchmark: reading a character, its animation and its body file, two checkouts against each other.

Issue 88's bar: checking what comes in (glTF's rules, body.json's, the input door) leaves reading a
valid character or body as fast as before, within 5 %. Each checkout runs in a process of its own
(imported from its own root through PYTHONPATH) that reads the files once per request; requests
alternate A, B, B, A, ... so the machine's drift falls on both alike. Each pair gives a ratio (B's
time over A's: below 1, B is faster); the median comes with a bootstrap 90 % interval.

    git worktree add --detach ../before <commit>
    python tools/bench_reading.py ../before . --character C.glb --animated A.glb --body B.json --pairs 30

Workloads: ``character`` (the skinned mesh and skeleton of a GLB, ``read_character``), ``animation``
(a GLB's animation as canonical motion, ``load_motion``), ``body`` (``read_body``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from machine import cpu_description

WORKER = r"""
import json, sys, time
from hrr_garment.body.body_file import read_body
from hrr_garment.body.character import read_character
from hrr_garment.motion.io import load_motion
files = json.loads(sys.argv[1])
work = {
    "character": lambda: read_character(files["character"]),
    "animation": lambda: load_motion(files["animated"]),
    "body": lambda: read_body(files["body"]),
}
for name in work.values():
    name()  # imports and caches warmed before any timing
print("ready", flush=True)
for line in sys.stdin:
    t0 = time.perf_counter()
    work[line.strip()]()
    print(time.perf_counter() - t0, flush=True)
"""


class Checkout:
    """One checkout's worker process."""

    def __init__(self, root: Path, files: dict):
        env = {**os.environ, "PYTHONPATH": str(root.resolve()), "OMP_NUM_THREADS": "1"}
        self.process = subprocess.Popen(
            [sys.executable, "-c", WORKER, json.dumps(files)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=env,
            cwd="/",
        )
        if self.process.stdout.readline().strip() != "ready":
            raise SystemExit(f"bench_reading: {root} could not read the files")

    def time(self, workload: str) -> float:
        self.process.stdin.write(workload + "\n")
        self.process.stdin.flush()
        return float(self.process.stdout.readline())


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("a", type=Path, help="the reference checkout")
    p.add_argument("b", type=Path, help="the checkout measured against it")
    p.add_argument("--character", type=Path, required=True, help="a skinned GLB")
    p.add_argument("--animated", type=Path, required=True, help="a GLB with an animation")
    p.add_argument("--body", type=Path, required=True, help="a body.json")
    p.add_argument("--pairs", type=int, default=30)
    args = p.parse_args()
    files = {k: str(getattr(args, k).resolve()) for k in ("character", "animated", "body")}
    a, b = Checkout(args.a, files), Checkout(args.b, files)
    print(cpu_description())
    rng = np.random.default_rng(0)
    for workload in ("character", "animation", "body"):
        ratios, ta, tb = [], [], []
        for k in range(args.pairs):
            order = (a, b) if k % 2 == 0 else (b, a)
            times = {id(c): c.time(workload) for c in order}
            ta.append(times[id(a)])
            tb.append(times[id(b)])
            ratios.append(tb[-1] / ta[-1])
        ratios = np.array(ratios)
        boot = np.median(rng.choice(ratios, (2000, len(ratios))), axis=1)
        low, high = np.percentile(boot, [5, 95])
        print(
            f"{workload:10s} A {1000 * np.median(ta):8.2f} ms  B {1000 * np.median(tb):8.2f} ms  "
            f"B/A {np.median(ratios):.3f} (90 % interval {low:.3f}-{high:.3f}, {args.pairs} pairs)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
