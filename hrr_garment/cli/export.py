"""hrr-export: turn an out.h5 from hrr-animate into files engines and DCC tools read.

    hrr-export out.h5 -o dress.glb                       # morph-target animation, 1 mm keyframe bound
    hrr-export out.h5 --to glb -o dress.glb --tolerance 0 --with-body
    hrr-export out.h5 -o hero_dress.glb --character hero.glb   # on the character's own skinned mesh
    hrr-export out.h5 -o dress.usdc                      # time-sampled points (.usda for text)
    hrr-export out.h5 -o dress.pc2                       # + dress.obj base mesh, for Blender's Mesh Cache
    hrr-export out.h5 --to obj -o frames/                # one OBJ per frame
    hrr-export out.h5 -o dress.blend --with-body         # a Blender scene, written by Blender (HRR_BLENDER)

The format follows --to, else the output's extension (a folder means an OBJ sequence). Everything
is written atomically. GLB, USD need the ``export`` extra; .blend a Blender. See docs/export.md.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Sequence

from ..errors import InputError
from ..io_utils import refuse_input_as_output, require_suffix
from ._common import run_cli

_FORMATS = ("glb", "usd", "pc2", "obj", "blend")
_BY_SUFFIX = {
    ".glb": "glb",
    ".usd": "usd",
    ".usdc": "usd",
    ".usda": "usd",
    ".pc2": "pc2",
    "": "obj",
    ".blend": "blend",
}


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-export", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("animation", type=Path, help="out.h5 written by hrr-animate")
    p.add_argument("-o", "--output", type=Path, required=True, help="file to write (a folder for --to obj)")
    p.add_argument(
        "--to", choices=_FORMATS, default=None, help="format (default: from the output's extension)"
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=1.0,
        help="GLB (and .blend) keyframe reduction: max per-vertex deviation in mm from every frame "
        "(0: every frame)",
    )
    p.add_argument(
        "--with-body", action="store_true", help="also export the collision body (GLB, USD, .blend)"
    )
    p.add_argument(
        "--character",
        type=Path,
        default=None,
        metavar="GLB",
        help="GLB: put the character's own skinned mesh in, posed by the clip (out.h5 from hrr-animate "
        "--body on the same character)",
    )
    p.add_argument(
        "--no-normals",
        action="store_true",
        help="GLB: leave the vertex normals out (about half the file; engines then shade flat or recompute)",
    )
    return p


def _size(paths: list[Path]) -> str:
    total = sum(p.stat().st_size for p in paths)
    return f"{total / 2**20:.1f} MiB" if total >= 2**20 else f"{total / 1024:.1f} KiB"


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..data.animation_file import read_animation_h5

    fmt = args.to or _BY_SUFFIX.get(args.output.suffix.lower())
    if fmt is None:
        raise InputError(
            args.output, f"cannot tell the format from the extension; give --to {'|'.join(_FORMATS)}"
        )
    if not (math.isfinite(args.tolerance) and args.tolerance >= 0):  # NaN passes a plain "< 0"
        raise InputError("--tolerance", f"must be a finite number of millimetres >= 0, got {args.tolerance}")
    if args.no_normals and fmt != "glb":
        raise InputError(args.output, f"--no-normals is for glb, not {fmt}")
    if args.character is not None and fmt != "glb":
        raise InputError(args.output, f"--character is for glb, not {fmt}")
    if args.with_body and fmt in ("pc2", "obj"):
        raise InputError(args.output, f"--with-body is for glb, usd and blend, not {fmt}")
    require_suffix(args.output, tuple(s for s, f in _BY_SUFFIX.items() if f == fmt), f"--to {fmt}")
    for output in (args.output, args.output.with_suffix(".obj")) if fmt == "pc2" else (args.output,):
        refuse_input_as_output(output, [args.animation, args.character])
    t0 = time.perf_counter()
    anim = read_animation_h5(args.animation)
    detail = ""
    if fmt == "glb":
        from ..export.character import skinned_character
        from ..export.glb import write_glb

        character = skinned_character(args.character) if args.character is not None else None
        report = write_glb(
            anim,
            args.output,
            tolerance=args.tolerance / 1000.0,
            with_body=args.with_body,
            normals=not args.no_normals,
            character=character,
        )
        written = [report.path]
        detail = (
            f"; {len(report.keyframes.frames)} keyframes of {anim.num_frames} frames, "
            f"max deviation {1000 * report.keyframes.max_error:.2f} mm (bound {args.tolerance:g} mm)"
        )
    elif fmt == "usd":
        from ..export.usd import write_usd

        written = [write_usd(anim, args.output, with_body=args.with_body)]
    elif fmt == "blend":
        from ..export.blend import write_blend

        written = [
            write_blend(anim, args.output, tolerance=args.tolerance / 1000.0, with_body=args.with_body)
        ]
    elif fmt == "pc2":
        from ..export.pointcache import write_pc2_with_obj

        written = list(write_pc2_with_obj(anim, args.output))
    else:
        from ..export.pointcache import write_obj_sequence

        written = write_obj_sequence(anim, args.output)
    names = str(written[0]) if len(written) <= 2 else f"{len(written)} files in {written[0].parent}"
    if len(written) == 2:
        names += f" + {written[1]}"
    print(
        f"wrote {names} ({fmt}, {_size(written)}): {anim.num_frames} frames of {anim.vertices.shape[1]} "
        f"vertices at {anim.fps:g} fps{detail}; {time.perf_counter() - t0:.1f} s"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-export``; returns the exit status."""
    return run_cli(_main, argv, "hrr-export")


if __name__ == "__main__":
    sys.exit(main())
