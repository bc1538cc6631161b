"""The sample mode's crowd step against the regression's, timed in one run on one machine.

    python tools/bench_sample.py --model hrr_work/models/dress --motion walk.bvh --crowd 32

Streams the same crowd (each character its own phase of the clip, a few metres apart) with the
regression and with the generative decoder's draw (mode sample, at the model's integration steps
or ``--steps``), alternating ``--repeat`` times so that the machine's drift falls on both; prints
each run's step p50 / p99 and the median ratio of the sample's p50 to the regression's (issue
bar: at most 1.5 at 32 characters), with the machine and its matrix-product reference.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from bench_inference import bench_crowd
from machine import cpu_description, gmac_reference_ms

from hrr_garment.inference.animator import Animator
from hrr_garment.motion.io import load_motion


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--model", required=True, help="a model with a generative decoder (hrr-train --stage sampler)"
    )
    parser.add_argument("--motion", required=True, help="a motion file the crowd plays")
    parser.add_argument("--crowd", type=int, nargs="+", default=[32], help="characters per crowd")
    parser.add_argument("--frames", type=int, default=200, help="steps per run, the first 20 warm-up")
    parser.add_argument("--repeat", type=int, default=3, help="alternations of the two modes")
    parser.add_argument(
        "--steps", type=int, default=None, help="the draw's integration steps (default: the model's)"
    )
    parser.add_argument("--decoder", choices=("full", "fast"), default="full")
    args = parser.parse_args()
    animator = Animator.load(args.model, push_out=True)
    animator.bundle.require_sampler()
    motion = load_motion(args.motion)
    out = {"cpu": cpu_description(), "reference_ms": round(gmac_reference_ms(), 3), "crowds": {}}
    for n in args.crowd:
        runs = {"regression": [], "sample": []}
        for _ in range(args.repeat):
            for mode in runs:
                steps = {"sample_steps": args.steps} if mode == "sample" and args.steps else {}
                runs[mode].append(
                    bench_crowd(
                        animator,
                        motion,
                        0.0,
                        n,
                        0.0,
                        args.frames,
                        decoder=args.decoder,
                        mode=mode,
                        changes=steps,
                    )
                )
        ratio = float(
            np.median([s["p50_ms"] / r["p50_ms"] for r, s in zip(runs["regression"], runs["sample"])])
        )
        out["crowds"][n] = {
            mode: [{k: r[k] for k in ("p50_ms", "p99_ms")} for r in results] for mode, results in runs.items()
        } | {"sample_over_regression_p50": round(ratio, 3)}
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
