"""hrr-motion: synthesize procedural motions, inspect motion files, compute features, write a clip's poses
as an engine hands them over."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import InputError
from ..io_utils import atomic_path, refuse_input_as_output, require_suffix, strict_json
from ..motion.features import motion_features
from ..motion.gltf_animation import gltf_summary
from ..motion.gltf_file import GLTF_SUFFIXES
from ..motion.io import load_motion, save_motion
from ..motion.poses import motion_to_poses
from ..motion.skeleton import JOINT_NAMES
from ..motion.synth import KINDS, kind_parameters, synthesize
from ..motion.windows import DEFAULT_WINDOW
from ._common import add_fps_option, run_cli

# what the commands that write a file derived from a motion file write: its suffixes, its name
_WRITTEN = {"features": ((".npy",), "the feature array"), "poses": ((".npz",), "the poses")}


def _add_load_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--unit-scale",
        type=float,
        default=None,
        help="metres per BVH file unit (default: detect from standing height)",
    )
    p.add_argument(
        "--joint-map",
        type=Path,
        default=None,
        help="YAML mapping canonical joint names to the file's joint names",
    )
    p.add_argument(
        "--no-ground",
        action="store_true",
        help="keep the file's vertical placement instead of standing the feet on y=0",
    )
    p.add_argument(
        "--animation",
        default=None,
        metavar="NAME",
        help="which animation of a glTF / GLB file, by name or index (default: the first)",
    )
    add_fps_option(p)


def _load(args: argparse.Namespace):
    return load_motion(
        args.file,
        unit_scale=args.unit_scale,
        joint_map=args.joint_map,
        ground=not args.no_ground,
        source_fps=args.fps,
        animation=args.animation,
    )


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hrr-motion", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("synth", help="generate a procedural motion")
    p.add_argument("kind", choices=sorted(KINDS))
    p.add_argument("--seconds", type=float, default=6.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="pin a kind parameter (see 'hrr-motion kinds')",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="native motion .npz")
    sub.add_parser("kinds", help="list procedural kinds and their parameters")
    p = sub.add_parser("info", help="summary of a motion file after retargeting and resampling")
    p.add_argument("file", type=Path)
    p.add_argument("--json", action="store_true")
    _add_load_options(p)
    p = sub.add_parser("features", help="write the (T, 124) float32 feature array")
    p.add_argument("file", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True, help="the features as .npy")
    p.add_argument(
        "--window", type=int, default=DEFAULT_WINDOW, help="minimum clip length in frames (one window)"
    )
    _add_load_options(p)
    p = sub.add_parser(
        "poses", help="write the clip as an engine hands poses over: local quaternions and roots (.npz)"
    )
    p.add_argument("file", type=Path)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="npz of rotations (T, 22, 4) x y z w, root (T, 3), fps and joint_names",
    )
    _add_load_options(p)
    return parser


def _body(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "kinds":
        for kind in KINDS:
            print(f"{kind:14s} {', '.join(kind_parameters(kind)) or '-'}")
        return 0
    if args.command == "synth":
        params = {}
        for item in args.param:
            name, _, value = item.partition("=")
            try:
                params[name] = float(value)
            except ValueError:
                raise InputError("--param", f"{item!r} is not NAME=NUMBER") from None
        motion = synthesize(args.kind, args.seconds, args.seed, **params)
        save_motion(motion, args.output)
        print(f"wrote {args.output} ({motion.num_frames} frames, {motion.duration_s:.2f} s)")
        return 0
    if args.command in _WRITTEN:  # before reading: a wrong output is refused before any work
        require_suffix(args.output, *_WRITTEN[args.command])
        refuse_input_as_output(args.output, [args.file])
    motion = _load(args)
    if args.command == "poses":
        rotations, root = motion_to_poses(motion)
        with atomic_path(args.output) as tmp, open(tmp, "wb") as fh:  # a handle: numpy appends .npz to a name
            np.savez(
                fh,
                rotations=rotations,
                root=root,
                fps=np.float64(motion.fps),
                joint_names=np.array(JOINT_NAMES),
            )
        print(
            f"wrote {args.output}: {len(rotations)} poses of {len(JOINT_NAMES)} joints at {motion.fps:g} fps"
        )
        return 0
    if args.command == "info":
        summary = motion.summary()
        if args.file.suffix.lower() in GLTF_SUFFIXES:  # which animation this is, and the file's others
            summary.update(gltf_summary(args.file, args.animation))
        if args.json:
            print(strict_json(summary, indent=2))  # a non-finite value prints as null, never NaN
        else:
            for key, value in summary.items():
                if key == "animations":
                    value = "".join(
                        f"\n  {a['index']}: {a['name']!r} {a['duration_s']:g} s, {a['keyframes']} keyframes, "
                        f"{a['frames_30fps']} frames at 30 fps"
                        for a in value
                    )
                print(f"{key:28s} {value}")
        return 0
    feats = motion_features(motion)
    if feats.shape[0] < args.window:
        raise InputError(
            args.file,
            f"clip has {feats.shape[0]} frames at 30 fps, shorter than one window of {args.window} frames",
        )
    with atomic_path(args.output) as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, feats)
    print(f"wrote {args.output} {feats.shape} float32")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-motion``; returns the exit status."""
    return run_cli(_body, argv, "hrr-motion")


if __name__ == "__main__":
    sys.exit(main())
