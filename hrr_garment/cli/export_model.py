"""hrr-export-model: a trained model's streaming step for engines that cannot call Python.

    hrr-export-model --model hrr_work/models/dress-real-quick --onnx -o dress.onnx
    hrr-export-model --garment dress --onnx -o hero_dress.onnx --body hero.json
    hrr-export-model --model DIR --onnx -o dress.onnx --check walk.bvh   # against the Python stream
    hrr-export-model --model DIR --onnx -o dress.onnx --decoder fast --push subspace   # the game's step
    hrr-export-model --model DIR --onnx -o drawn.onnx --mode sample --check walk.bvh --seed 3

Writes dress.onnx (one graph: a frame of N characters' poses in, their garments' world vertices
out at 30 frames a second, the window state as explicit inputs and outputs; the regression path
with the push-out, or with --mode sample the generative decoder's draw, fed white noise) and
dress.tensors.npz (the garment's faces, the joint order, the retrieval database as tensors). With
--check, the clip is streamed through onnxruntime and through the Python stream and the largest
gap is printed; over 0.1 mm is an error. Needs the ``onnx`` extra. See docs/export.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..errors import InputError
from ..inference.run_settings import RunSettings
from ..io_utils import refuse_input_as_output, require_suffix
from ._common import (
    add_decoder_option,
    add_no_push_out_option,
    add_push_option,
    add_sample_options,
    run_cli,
    run_settings_error,
)

TOLERANCE_MM = 0.1  # the ONNX stream's largest gap from the Python stream that --check accepts


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-export-model", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--model", type=Path, default=None, help="trained model directory")
    p.add_argument("--garment", default=None, help="the newest model of this garment in the workspace")
    p.add_argument(
        "--onnx", action="store_true", help="write the streaming step as ONNX (the one format so far)"
    )
    p.add_argument(
        "-o", "--output", type=Path, required=True, help="the .onnx file (its tensors go beside it)"
    )
    p.add_argument(
        "--body",
        default=None,
        metavar="BODY",
        help="the characters' body: body.json or a skinned glTF / GLB character (default: the model's own)",
    )
    p.add_argument(
        "--allow-outside-body",
        action="store_true",
        help="export for a body unlike the model's training bodies anyway (warned)",
    )
    p.add_argument(
        "--material",
        default=None,
        metavar="CLOTH",
        help="a model across cloths: the cloth the graph's material input defaults to and --check streams "
        "(a fabric or values, as hrr-animate takes them; default: the model's cloth)",
    )
    add_no_push_out_option(p, help="leave the push-out out of the graph (an engine with its own collision)")
    add_decoder_option(p)
    add_push_option(p)
    p.add_argument(
        "--mode",
        choices=("regression", "sample"),
        default="regression",
        help="the path in the graph: the regression (default), or the sample mode's draw (the generative "
        "decoder; the engine feeds each character's white noise, docs/export.md)",
    )
    add_sample_options(p)
    p.add_argument(
        "--settle",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="the settling lag after a stop in the graph (its state 'settled'; docs/inference.md): the "
        "time constant of the garment's lag towards the model's prediction (default 0: none)",
    )
    p.add_argument(
        "--check",
        type=Path,
        default=None,
        metavar="CLIP",
        help="stream this motion file through the graph and the Python stream and compare",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar (the export's stages and its clock)")
    return p


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    if not args.onnx:
        raise InputError("hrr-export-model", "choose the format: --onnx")
    if args.garment is None and args.model is None:
        raise InputError("hrr-export-model", "give --garment NAME or --model DIR")
    require_suffix(args.output, (".onnx",), "an ONNX model")
    drawing = _run_changes(args)
    from ..export.onnx_model import check_onnx, export_onnx, tensors_path

    for output in (args.output, tensors_path(args.output)):  # the graph and its companion
        refuse_input_as_output(output, [args.check, args.body])
    from ..inference.animator import Animator, find_model
    from ..motion.io import load_motion

    motion = (
        load_motion(args.check) if args.check else None
    )  # a bad clip is refused before the export's minute
    model_dir = find_model(args.model or args.garment)
    animator = Animator.load(model_dir)
    if args.garment is not None and animator.bundle.garment != args.garment:
        raise InputError(model_dir, f"this model animates a {animator.bundle.garment}, not a {args.garment}")
    # the body made ready once (a character file is fitted once), for the export and the check
    body = animator.body(args.body, allow_outside=args.allow_outside_body) if args.body else None
    written = export_onnx(
        animator,
        args.output,
        body=body,
        push_out=not args.no_push_out,
        decoder=args.decoder,
        push=args.push,
        push_body=args.push_body,
        material=args.material,
        progress=not args.quiet,
        **drawing,
    )
    size = written.graph.stat().st_size / 2**20
    print(
        f"wrote {written.graph} ({size:.1f} MiB, {written.vertices} vertices) and {written.tensors.name} "
        f"in {written.seconds:.0f} s"
    )
    print(f"motion licence: {animator.bundle.manifest.licences.statement}")
    if motion is None:
        return 0
    gap = check_onnx(animator, written.graph, motion, body=body, seed=args.seed, material=args.material)
    print(
        f"{args.check.name}: {gap['frames']} frames, ONNX - Python stream max {gap['max_mm']:.4f} mm, mean "
        f"{gap['mean_mm']:.4f} mm; median step ONNX {gap['onnx_ms']:.2f} ms, Python {gap['python_ms']:.2f} ms"
    )
    if gap["max_mm"] > TOLERANCE_MM:
        print(
            f"error: the graph departs from the Python stream by more than {TOLERANCE_MM} mm", file=sys.stderr
        )
        return 1
    return 0


def _run_changes(args: argparse.Namespace) -> dict:
    """The run's mode, its draw's steps and its settling lag; an InputError naming the flag for a
    value they cannot take (checked with the seed, which --check draws with, before the export's
    minute)."""
    changes = {"mode": args.mode, "sample_steps": args.sample_steps, "settle": args.settle}
    try:
        RunSettings(**changes, seed=args.seed)
    except (TypeError, ValueError) as exc:
        raise run_settings_error(exc) from None
    return changes


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-export-model``; returns the exit status."""
    return run_cli(_main, argv, "hrr-export-model")


if __name__ == "__main__":
    sys.exit(main())
