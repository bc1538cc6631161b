"""hrr-preview: shaded renders of an animation file from hrr-animate.

    hrr-preview out.h5 -o dress.gif                         # front and left views, body shown
    hrr-preview out.h5 -o dress.mp4 --views front three-quarter back --color-mode
    hrr-preview out.h5 -o sheet.png --frames 8              # a contact sheet of 8 frames
    hrr-preview silk.h5 --beside denim.h5 -o cloths.gif     # one clip in two cloths, side by side
    hrr-preview out.h5 -o dress.gif --no-body --every 2 --size 240

--color-mode paints the garment orange on frames that were retrieved from the database and blue on
regressed ones. MP4 needs an ffmpeg (the ``video`` extra ships one). See docs/export.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Sequence

from ._common import run_cli


def _parser() -> argparse.ArgumentParser:
    from ..export.ortho_render import VIEWS

    p = argparse.ArgumentParser(
        prog="hrr-preview", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("animation", type=Path, help="out.h5 written by hrr-animate")
    p.add_argument("-o", "--output", type=Path, required=True, help=".gif, .mp4 or .png (contact sheet)")
    p.add_argument(
        "--views", nargs="+", default=["front", "left"], choices=list(VIEWS), help="cameras, side by side"
    )
    p.add_argument(
        "--with-body", dest="with_body", action="store_true", default=True, help="draw the body (default)"
    )
    p.add_argument("--no-body", dest="with_body", action="store_false", help="garment only")
    p.add_argument(
        "--color-mode", action="store_true", help="colour retrieved frames orange, regressed ones blue"
    )
    p.add_argument(
        "--beside",
        type=Path,
        action="append",
        default=[],
        metavar="OTHER.h5",
        help="another animation of the same clip drawn to the right (repeatable): the same dress in "
        "another cloth, say (each frame's label names the cloth where the file records one)",
    )
    p.add_argument("--size", type=int, default=360, help="pixels per view (default 360)")
    p.add_argument("--elevation", type=float, default=12.0, help="camera elevation in degrees (default 12)")
    p.add_argument("--every", type=int, default=1, help="render every N-th frame (GIF/MP4)")
    p.add_argument("--frames", type=int, default=6, help="frames in a PNG contact sheet (default 6)")
    return p


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..data.animation_file import read_animation_h5
    from ..export.video import PreviewStyle, write_preview

    t0 = time.perf_counter()
    style = PreviewStyle(
        views=tuple(args.views),
        size=args.size,
        elevation=args.elevation,
        with_body=args.with_body,
        color_mode=args.color_mode,
    )
    anim = read_animation_h5(args.animation)
    beside = tuple(read_animation_h5(other) for other in args.beside)
    path = write_preview(anim, args.output, style, every=args.every, sheet_frames=args.frames, beside=beside)
    print(
        f"wrote {path} ({path.stat().st_size / 2**20:.1f} MiB) from {anim.num_frames} frames; "
        f"{time.perf_counter() - t0:.1f} s"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-preview``; returns the exit status."""
    return run_cli(_main, argv, "hrr-preview")


if __name__ == "__main__":
    sys.exit(main())
