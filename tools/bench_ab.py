"""Benchmark: two checkouts of the package timed against each other, one pass at a time.

On a shared two-core machine whole benchmark runs drift by 10-25 % from one to the next, so two
commits timed in turn by ``bench_inference.py`` cannot be told apart at a few per cent. Here each
checkout runs in a process of its own that builds the same random-weight model (the
``bench_inference.py`` of that checkout: 4,156 vertices, 5,700 database windows, the fast decoder,
a 5 s procedural walk at the median window entropy's tau) and then times one pass of a workload per
request. The passes alternate A, B, B, A, ... workload by workload, so the machine's drift falls on
both alike; each pair gives a speed ratio (A's time over B's: above 1, B is faster), and the median
ratio comes with a bootstrap 90 % interval.

Workloads: ``hybrid`` ``regression`` ``retrieval`` ``detail`` (offline, push-out off), ``push``
(offline hybrid with the push-out), ``crowd1`` ``crowd8`` ``crowd64`` (the median step of that many
characters streamed together for 40 frames).

    git worktree add --detach ../before <commit>
    python tools/bench_ab.py ../before . --pairs 30                    # every workload
    python tools/bench_ab.py ../before . --pairs 40 --workloads push detail crowd64

Each checkout must import as ``hrr_garment`` from its own root with this Python (an editable
install elsewhere is overridden by PYTHONPATH); its ``bench_inference.py`` must have
``random_bundle``, ``bench_crowd`` and ``_median_entropy_tau`` (every commit since the crowd's
benchmark). Checkouts from before the push-out was named so (``collision=``) are driven by that name.
"""

from __future__ import annotations

import argparse
import inspect
import os
import random
import statistics
import subprocess
import sys
import time
from pathlib import Path

WORKLOADS = ("hybrid", "regression", "retrieval", "detail", "push", "crowd1", "crowd8", "crowd64")
CROWD_FRAMES = 40  # a crowd pass: 40 steps, its median step timed


def serve(workloads: list[str]) -> None:
    """The worker: build the model of this checkout, warm each of ``workloads`` once, then time one
    pass per workload name read from stdin, printing seconds."""
    sys.path.insert(0, str(Path.cwd() / "tools"))
    import bench_inference as bench

    from hrr_garment import Animator, synthesize

    animator = Animator(bench.random_bundle(4156, 5700))
    motion = synthesize("walk_curve", 5.0, seed=0)
    tau = bench._median_entropy_tau(animator.bundle, motion)
    # the push-out's switch was called collision before issue 81's one run request
    switch = "push_out" if "push_out=True" in inspect.getsource(bench) else "collision"

    def one_pass(name: str) -> float:
        if name.startswith("crowd"):
            step = bench.bench_crowd(animator, motion, tau, int(name[5:]), 0.0, CROWD_FRAMES, decoder="fast")
            return step["p50_ms"] / 1000.0
        mode, push = ("hybrid", True) if name == "push" else (name, False)
        start = time.perf_counter()
        animator.animate(motion, mode=mode, tau=tau, decoder="fast", **{switch: push})
        return time.perf_counter() - start

    for name in workloads:
        one_pass(name)
    print("ready", flush=True)
    for line in sys.stdin:
        print(f"{one_pass(line.strip()):.6f}", flush=True)


class Worker:
    """A checkout's worker process."""

    def __init__(self, root: Path, workloads: list[str]):
        env = dict(os.environ, PYTHONPATH=str(root))
        self.process = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "--serve", "--workloads", *workloads],
            cwd=root,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        if self.process.stdout.readline().strip() != "ready":
            raise SystemExit(f"{root}: its worker did not start (see the error above)")

    def time(self, workload: str) -> float:
        self.process.stdin.write(workload + "\n")
        self.process.stdin.flush()
        return float(self.process.stdout.readline())

    def close(self) -> None:
        self.process.stdin.close()
        self.process.wait()


def interval(ratios: list[float], rng: random.Random, draws: int = 4000) -> tuple[float, float]:
    """The bootstrap 90 % interval of the median of ``ratios``."""
    medians = sorted(statistics.median(rng.choices(ratios, k=len(ratios))) for _ in range(draws))
    return medians[int(0.05 * draws)], medians[int(0.95 * draws) - 1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", nargs="?", type=Path, help="the first checkout (the reference)")
    parser.add_argument("b", nargs="?", type=Path, help="the second checkout")
    parser.add_argument("--pairs", type=int, default=30, help="passes of each checkout per workload")
    parser.add_argument("--workloads", nargs="+", choices=WORKLOADS, default=list(WORKLOADS))
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.serve:
        serve(args.workloads)
        return 0
    if args.a is None or args.b is None or args.pairs < 2:
        parser.error("give two checkouts and at least 2 pairs")
    for root in (args.a, args.b):
        if not (root / "hrr_garment").is_dir() or not (root / "tools" / "bench_inference.py").is_file():
            parser.error(
                f"{root}: not a checkout of hrr_garment (no hrr_garment/ or tools/bench_inference.py)"
            )
    workers = [Worker(args.a.resolve(), args.workloads), Worker(args.b.resolve(), args.workloads)]
    times = {w: ([], []) for w in args.workloads}
    try:
        for i in range(args.pairs):
            order = (0, 1) if i % 2 == 0 else (1, 0)  # A B, then B A: drift within a pair cancels too
            for workload in args.workloads:
                for k in order:
                    times[workload][k].append(workers[k].time(workload))
    finally:
        for worker in workers:
            worker.close()
    rng = random.Random(0)
    print(f"A = {args.a}, B = {args.b}; {args.pairs} pairs, passes alternating A B / B A")
    print("| workload | A median (ms) | B median (ms) | speed B / A (median of pairs) | 90 % interval |")
    print("|---|---:|---:|---:|---|")
    for workload, (a, b) in times.items():
        ratios = [x / y for x, y in zip(a, b)]
        lo, hi = interval(ratios, rng)
        print(
            f"| {workload} | {1000 * statistics.median(a):.2f} | {1000 * statistics.median(b):.2f} | "
            f"{statistics.median(ratios):.3f} | {lo:.3f}-{hi:.3f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
