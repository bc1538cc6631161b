"""hrr-import: add your own garment simulation to a dataset (same format as hrr-simulate's).

Example::

    hrr-import --garment my_dress --template my_dress.obj --attached waistband \\
        --motion walk.bvh --frames sim_frames/ -o hrr_work/datasets/my_dress.h5

The template OBJ is the garment in the canonical rest pose; frames (a folder of OBJ files or an npz
with ``vertices`` (T, V, 3)) keep the template's vertex order and the motion's world frame.
Importing into an existing dataset adds the sequence (the template must be the same).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..data.importer import frames_to_sequence, import_sequence, read_frames
from ..garment.obj import load_garment_obj
from ..motion.io import load_motion
from ._common import add_fps_option, run_cli


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-import", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--garment", required=True, help="garment name stored in the dataset")
    p.add_argument("--template", type=Path, required=True, help="garment OBJ in the rest pose")
    p.add_argument(
        "--attached", default=None, metavar="GROUP", help="OBJ group whose vertices follow the body"
    )
    p.add_argument("--attached-file", type=Path, default=None, help="file of 0-based attached vertex indices")
    p.add_argument(
        "--motion",
        type=Path,
        required=True,
        help="the motion that drove the simulation (BVH, AMASS or native npz)",
    )
    p.add_argument(
        "--frames", type=Path, required=True, help="folder of per-frame OBJ files, or npz with 'vertices'"
    )
    p.add_argument("--frames-fps", type=float, default=30.0, help="rate of the frames (default 30)")
    p.add_argument("--frames-scale", type=float, default=1.0, help="metres per frame unit (default 1)")
    p.add_argument("--name", default=None, help="sequence name (default: the motion file's name)")
    p.add_argument("--unit-scale", type=float, default=None, help="metres per BVH unit (default: detect)")
    add_fps_option(p)
    p.add_argument("-o", "--output", type=Path, required=True, help="dataset .h5 to create or extend")
    return p


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    template = load_garment_obj(
        args.template, args.garment, attached_group=args.attached, attached_file=args.attached_file
    )
    # Keep the file's placement: the frames are in the motion's world frame.
    motion = load_motion(args.motion, unit_scale=args.unit_scale, ground=False, source_fps=args.fps)
    frames = read_frames(args.frames)
    record = frames_to_sequence(
        args.name or args.motion.stem,
        template,
        motion,
        frames=frames,
        source=str(args.frames),
        frames_fps=args.frames_fps,
        frames_scale=args.frames_scale,
    )
    path = import_sequence(args.output, template, record)
    print(
        f"imported {record.name}: {len(record.garment)} frames x {template.num_vertices} vertices -> {path}"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-import``; returns the exit status."""
    return run_cli(_main, argv, "hrr-import")


if __name__ == "__main__":
    sys.exit(main())
