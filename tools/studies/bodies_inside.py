"""Analysis: how much of the cloth a model puts inside each body before the push-out.

A model across bodies reads each body's twelve measures (docs/bodies.md); ``hrr-body info --model``
says whether each measure lies within the training bodies' range. This tool asks the model itself:
it animates clips on each body (the model's default mode, offline, the push-out off:
:mod:`hrr_garment.eval.inside_body`, which ``hrr-body info --model DIR --inside`` runs) and reports,
body by body and clip by clip, the vertices more than 5 mm inside the body (mean over frames and the
worst frame) and those inside at all, as ``hrr-eval``'s "inside before the push-out" counts them.
What it shows: bodies off the training bodies' shapes can lie inside every measure's range and
still take the cloth inside them (docs/results-bodies.md).

Bodies: ``scaled`` (the mannequin's bones and capsules 0.9-1.1 x, as ``bench_inference.py
--crowd-bodies`` makes them), ``anny`` (sampled as the bodies preset samples, another seed: the
bodies extra), or body files (body.json or a character's GLB). Bodies outside the model's range are
animated anyway, with the measures that are out listed in the report.

    python tools/studies/bodies_inside.py --model hrr_work/models/dress-real-quick-bodies \\
        --bodies scaled anny --count 9
    python tools/studies/bodies_inside.py --model DIR --bodies hero.json villain.glb --motion clip.bvh --json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hrr_garment.eval.inside_body import check_motion, cloth_inside
from hrr_garment.inference.animator import Animator
from hrr_garment.inference.character_body import read_body_argument
from hrr_garment.motion.io import load_motion

# the crowds' bodies are the inference benchmark's, one folder up (tools/)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_inference import crowd_bodies  # noqa: E402

SOURCES = ("scaled", "anny")


def named_bodies(sources: list[str], count: int) -> list[tuple[str, object]]:
    """(name, body record) of each source: ``count`` scaled mannequins or anny bodies, or a body file."""
    out = []
    for source in sources:
        if source in SOURCES:
            records = crowd_bodies(count, source)
            out += [(f"{source} {i} ({float(r.stature):.2f} m)", r) for i, r in enumerate(records)]
        else:
            out.append(read_body_argument(source))
    return out


def analyse(model: str, sources: list[str], motions: list[str], count: int = 9) -> dict:
    """Each body's and clip's :func:`~hrr_garment.eval.inside_body.cloth_inside` (the procedural
    curved walk when ``motions`` is empty)."""
    animator = Animator.load(model)
    clips = {Path(path).name: load_motion(path) for path in motions} or {
        "procedural walk_curve": check_motion()
    }
    rows = [
        {**cloth_inside(animator, motion, record, name=name).to_dict(), "clip": clip}
        for name, record in named_bodies(sources, count)
        for clip, motion in clips.items()
    ]
    return {"model": model, "rows": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True, help="a trained model's folder")
    parser.add_argument(
        "--bodies",
        nargs="+",
        default=["scaled"],
        help="scaled, anny, or body files (body.json, a character's .glb)",
    )
    parser.add_argument("--count", type=int, default=9, help="bodies of each of scaled and anny")
    parser.add_argument(
        "--motion", nargs="*", default=[], help="clips (BVH / npz); default a procedural walk"
    )
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args()
    if args.count < 1:
        parser.error("--count must be at least 1")
    report = analyse(args.model, args.bodies, args.motion, args.count)
    if args.json:
        print(json.dumps(report))
        return
    print("| body | clip | inside > 5 mm % | worst frame % | inside at all % | out of range |")
    print("|---|---|---:|---:|---:|---|")
    for r in report["rows"]:
        print(
            f"| {r['body_name']} | {r['clip']} | {r['inside_pct']:.2f} | {r['inside_worst_pct']:.2f} | "
            f"{r['inside_any_pct']:.2f} | {'; '.join(r['outside_range']) or '-'} |"
        )


if __name__ == "__main__":
    main()
