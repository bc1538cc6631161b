"""Benchmark: what the checks where poses enter cost a crowd's step, and what the detail mode's fold
strain limit and fold reads cost it, each as a share of the step, measured in one run.

    python tools/bench_checks.py --model hrr_work/models/dress-real-quick-bodies-contact --crowd 32

A crowd of N characters is pushed ``--steps`` times (quaternions and roots, as an engine hands
them over; the model's default mode), and the step's median is the denominator. The entry checks
are timed on the same poses: the conversion to a Motion with every check (``poses_to_motion``:
shapes, real and finite values, unit quaternions, roots within 10 km) and the teleport test.
The fold limit is timed as ``add_folds`` with the template's edge limits against without, on N
frames of the model's regression with N database frames' folds; the fold read as N characters'
reads of two rows each (a cross-fade: the most the fold track reads). Medians of ``--repeat`` timings
each; the shares are of the step median measured in between, so a busy machine inflates both.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def _median_us(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e6 * float(np.median(times))


def main() -> None:
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.detail import add_folds
    from hrr_garment.motion.poses import poses_to_motion
    from hrr_garment.motion.rotations import matrix_to_quat
    from hrr_garment.motion.synth import synthesize

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", required=True)
    p.add_argument("--crowd", type=int, default=32)
    p.add_argument("--steps", type=int, default=120)
    p.add_argument("--repeat", type=int, default=200)
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    animator = Animator.load(args.model)
    clip = synthesize("walk_curve", 8.0, seed=1)
    quats = matrix_to_quat(clip.local_rotations.astype(np.float64))[..., [1, 2, 3, 0]]  # x, y, z, w
    n, frames = args.crowd, clip.num_frames
    starts = np.arange(n) * 7 % frames
    offsets = np.stack([np.arange(n) * 1.5, np.zeros(n), np.zeros(n)], 1)  # each character in its own place
    crowd = animator.crowd()
    steps = []
    for t in range(args.steps):
        f = (starts + t) % frames
        start = time.perf_counter()
        crowd.push(quats[f], clip.root_translation[f] + offsets)
        steps.append(time.perf_counter() - start)
    step_us = 1e6 * float(np.median(steps[20:]))  # after the first windows fill
    f = (starts + args.steps) % frames
    entry_us = _median_us(lambda: poses_to_motion(quats[f], clip.root_translation[f] + offsets), args.repeat)
    poses = poses_to_motion(quats[f], clip.root_translation[f] + offsets)
    keys = list(range(n))
    teleport_us = _median_us(lambda: crowd._restart_teleported(keys, poses), args.repeat)  # noqa: SLF001 - the check alone
    store = animator.bundle.folds
    result = {
        "model": args.model,
        "crowd": n,
        "mode": str(crowd.mode),
        "step_median_us": round(step_us, 1),
        "entry_checks_us": round(entry_us, 1),
        "teleport_check_us": round(teleport_us, 1),
    }
    if store is not None:
        local = animator.animate(clip.slice(0, n), mode="regression", push_out=False).vertices.astype(
            np.float64
        )
        rows = np.stack([np.arange(n) * 97 % len(store.levels), np.zeros(n, np.int64)], 1)
        folds = store.folds(rows, np.stack([np.ones(n), np.zeros(n)], 1))
        plain = _median_us(
            lambda: add_folds(local, folds, animator.smoothing, store.passes), args.repeat // 4
        )
        limited = _median_us(
            lambda: add_folds(local, folds, animator.smoothing, store.passes, limits=animator.edge_limits),
            args.repeat // 4,
        )
        # each character's fold read at a cross-fade (two rows), the most the fold track reads in a step
        fading = np.stack([rows[:, 0], (rows[:, 0] + 1) % len(store.levels)], 1)
        read = _median_us(lambda: store.folds(fading, np.full((n, 2), 0.5)), args.repeat)
        result.update(
            add_folds_us=round(plain, 1),
            add_folds_limited_us=round(limited, 1),
            fold_limit_share=round((limited - plain) / step_us, 4),
            fold_encoding=store.encoding,
            fold_read_us=round(read, 1),
            fold_read_share=round(read / step_us, 4),
        )
    result.update(entry_share=round((entry_us + teleport_us) / step_us, 4))
    if args.json:
        print(json.dumps(result))
        return
    for key, value in result.items():
        print(f"{key:24s} {value}")


if __name__ == "__main__":
    main()
