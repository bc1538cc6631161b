"""hrr-body: make a body from the parametric model, or look at a body file.

    hrr-body make -o tall.json --height 0.8 --weight 0.3 --gender 1     # anny's phenotype, each in [0, 1]
    hrr-body make -o average.json                                        # its average adult
    hrr-body info tall.json [--json]

``make`` builds anny's body of that shape (the ``bodies`` extra; the first run builds its blend
shapes, about a minute, cached under the workspace), fits the canonical skeleton's bone lengths and
the collision capsules to it and writes body.json (docs/bodies.md), reporting its height and how
closely the capsules follow its surface.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import fields
from pathlib import Path
from typing import Sequence

from ..body.body_file import read_body, write_body
from ..body.parametric import BodyShape
from ..errors import InputError
from ._common import run_cli


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="hrr-body", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    make = sub.add_parser("make", help="a body of the parametric model's shape -> body.json")
    for f in fields(BodyShape):
        make.add_argument(f"--{f.name}", type=float, default=0.5, help=f"anny's {f.name}, in [0, 1] (default 0.5)")
    make.add_argument("-o", "--output", type=Path, required=True, help="body.json to write")
    info = sub.add_parser("info", help="what a body file holds")
    info.add_argument("body", type=Path)
    info.add_argument("--json", action="store_true")
    return p


def _summary(record) -> dict:
    rest = record.skeleton.rest_positions()
    return {"pelvis_height_m": round(record.pelvis_height, 4),
            "stature_m": round(record.stature, 4),
            "hip_width_m": round(float(rest[1, 0] - rest[2, 0]), 4),
            "shoulder_width_m": round(float(rest[16, 0] - rest[17, 0]), 4),
            "leg_length_m": round(float(rest[1, 1] - rest[7, 1]), 4),
            "capsules": len(record.body.capsules), "shape": record.shape,
            "fit": record.report.to_dict() if record.report else None}


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "info":
        summary = _summary(read_body(args.body))
        print(json.dumps(summary) if args.json else "\n".join(f"{k}: {v}" for k, v in summary.items()))
        return 0
    if args.output.suffix.lower() != ".json":
        raise InputError(args.output, "a body file is written as .json")
    try:
        shape = BodyShape(**{f.name: getattr(args, f.name) for f in fields(BodyShape)})
    except ValueError as exc:
        raise InputError("hrr-body", str(exc)) from None
    from ..body.parametric import parametric_body

    body = parametric_body(shape)
    write_body(args.output, body)
    summary = _summary(read_body(args.output))
    fit = body.fitted.report
    print(f"wrote {args.output}: {summary['stature_m']:.3f} m tall, pelvis {summary['pelvis_height_m']:.3f} m over the soles; capsules within {fit.mean_mm:.1f} mm of the surface on average "
          f"(95th percentile {fit.p95_mm:.1f} mm)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-body``; returns the exit status."""
    return run_cli(_main, argv, "hrr-body")


if __name__ == "__main__":
    sys.exit(main())
