"""hrr-animate: animate a trained garment from a motion file.

    hrr-animate walk.bvh -o out.h5 --garment dress        # workspace model (full if present, else quick)
    hrr-animate clip.npz -o out.h5 --model hrr_work/models/dress-quick --mode retrieval
    hrr-animate walk.bvh -o out.h5 --garment dress --causal --no-push-out
    hrr-animate walk.bvh -o out.h5 --garment dress --detail-strength 1 --detail-base residual
    hrr-animate walk.bvh -o out.h5 --model DIR --body hero.json      # on your character's body
    hrr-animate hero.glb --animation Walk -o out.h5 --model DIR --body hero.glb
    hrr-animate walk.bvh -o out.h5 --model DIR --material silk       # a model trained across cloths
    hrr-animate walk.bvh -o out.h5 --model DIR --material jersey,bend=8e-6

MOTION: BVH, glTF / GLB (``--animation NAME``), AMASS-style npz or the native npz (resampled to 30 fps).
Output: out.h5 (see docs/inference.md), written atomically. Offline (default) blends windows centred on each
frame; ``--causal`` gives exactly what the streaming API gives (no future frames).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Sequence

from ..artifacts.gate_signals import GATE_SIGNALS
from ..errors import InputError
from ..inference.modes import Mode
from ..io_utils import refuse_input_as_output, require_writable_place
from ..native import PRECISIONS
from ._common import (
    add_decoder_option,
    add_detail_options,
    add_fps_option,
    add_no_push_out_option,
    add_push_option,
    add_sample_options,
    detail_look,
    run_cli,
    run_settings_of,
)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-animate", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("motion", type=Path, help="BVH, glTF / GLB, AMASS npz or native npz")
    p.add_argument("-o", "--output", type=Path, required=True, help="out.h5 to write")
    p.add_argument("--garment", default=None, help="use the workspace model of this garment")
    p.add_argument("--model", type=Path, default=None, help="model bundle directory (instead of --garment)")
    p.add_argument(
        "--mode",
        default=Mode.AUTO.value,
        choices=[m.value for m in Mode],
        help="auto (default): the mode this model was calibrated to run, the most plausible cloth within "
        "3 %% of the most accurate (bundle.json 'auto'); hybrid: the calibrated gate between retrieval "
        "and regression; residual: regression plus the matched window's detail; detail: the "
        "regression's shape with simulated folds from the database; direct: the baseline, when the model "
        "has it (hrr-train --stage direct); sample: a draw of the cloth's distribution by the generative "
        "decoder, frame after frame (causal; --seed picks the draw), when the model has it (hrr-train "
        "--stage sampler)",
    )
    p.add_argument(
        "--gate",
        default=None,
        choices=GATE_SIGNALS,
        help="what the hybrid thresholds: the motion code's entropy (the paper's), the match's code "
        "similarity or its motion distance (default: the model's calibrated choice)",
    )
    p.add_argument(
        "--tau",
        type=float,
        default=None,
        help="the gate's threshold (default: the model's calibrated one); --gate or --tau with the default "
        "mode runs the hybrid, whose settings they are",
    )
    add_detail_options(p)
    p.add_argument(
        "--body",
        default=None,
        metavar="BODY",
        help="animate on this body: body.json (hrr-body make / fit / nearest) or a skinned glTF / GLB "
        "character, fitted as hrr-body fit does (default: the model's own body)",
    )
    p.add_argument(
        "--allow-outside-body",
        action="store_true",
        help="animate a body unlike the model's training bodies anyway (warned), rather than refuse it",
    )
    p.add_argument(
        "--material",
        default=None,
        metavar="CLOTH",
        help="the cloth: a fabric (silk, denim, ...), a fabric with values changed (jersey,bend=8e-6), "
        "values (density=0.2,bend=1e-5) or a YAML file of them; within the range the model was trained in "
        "(default: the model's cloth)",
    )
    p.add_argument(
        "--allow-outside-material",
        action="store_true",
        help="animate a cloth unlike the model's training cloths anyway (warned), rather than refuse it",
    )
    add_no_push_out_option(p, help="skip the collision push-out")
    add_decoder_option(p)
    add_push_option(p)
    add_sample_options(p)
    p.add_argument("--causal", action="store_true", help="causal windows only, as the streaming API")
    p.add_argument(
        "--precision",
        choices=PRECISIONS,
        default=None,
        help="the mesh decoder's arithmetic: bfloat16 runs on AMX (recent Intel Xeons), about 3x faster, "
        "within hundredths of a millimetre on average (default: float32)",
    )
    p.add_argument(
        "--unit-scale", type=float, default=None, help="BVH length unit in metres (default: detected)"
    )
    p.add_argument(
        "--animation",
        default=None,
        metavar="NAME",
        help="which animation of a glTF / GLB file, by name or index (default: the first)",
    )
    add_fps_option(p)
    return p


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..inference.animator import Animator, find_model
    from ..motion.io import load_motion

    if args.garment is None and args.model is None:
        raise InputError("hrr-animate", "give --garment NAME or --model DIR")
    if args.output.suffix.lower() not in (".h5", ".hdf5"):
        raise InputError(args.output, "the output must be an .h5 file")
    require_writable_place(args.output)
    refuse_input_as_output(args.output, [args.motion, args.body])
    model_dir = find_model(args.model or args.garment)
    if args.model is None:
        print(f"model: {model_dir}")
    t0 = time.perf_counter()
    motion = load_motion(
        args.motion, unit_scale=args.unit_scale, source_fps=args.fps, animation=args.animation
    )
    # --gate/--tau run the hybrid, --detail-* the detail mode; asking both, or a mode without them, is refused
    settings = run_settings_of(
        args,
        "hrr-animate",
        detail=detail_look(args),
        push_out=not args.no_push_out,
        causal=args.causal,
        body=args.body,
        allow_outside=args.allow_outside_body,
        material=args.material,
        allow_outside_material=args.allow_outside_material,
        precision=args.precision,
    )
    animator = Animator.load(model_dir, settings)
    if args.garment is not None and animator.bundle.garment != args.garment:
        raise InputError(model_dir, f"this model animates a {animator.bundle.garment}, not a {args.garment}")
    anim = animator.animate(motion)
    anim.save(args.output)
    seconds = time.perf_counter() - t0
    # the gate decides in the hybrid only; the other modes retrieve always, never, or add a match's detail
    mode = Mode(anim.settings["mode"])
    gate = (
        f", gate {anim.settings['gate']} < {anim.settings['tau']:.3f}"
        if mode == Mode.HYBRID
        else f", folds x{anim.settings['detail_strength']:g} on the {anim.settings['detail_base']}"
        if mode == Mode.DETAIL
        else f", seed {anim.settings['seed']}, {anim.settings['sample_steps']} steps a frame"
        if mode == Mode.SAMPLE
        else ""
    )
    if anim.settings.get("swing", 1.0) != 1.0:
        gate += f", swing x{anim.settings['swing']:g}"
    if anim.settings.get("settle", 0.0):
        gate += f", settling over {anim.settings['settle']:g} s"
    used = (
        "a database match on every frame"
        if mode in (Mode.RESIDUAL, Mode.DETAIL)
        else f"retrieval usage {100 * anim.retrieval_usage:.1f} % of frames"
    )
    named = f"{args.mode} = {mode}" if args.mode != mode else str(mode)
    material = anim.material
    cloth = f" in {material.describe()}" if material is not None else ""
    print(
        f"wrote {args.output}: {anim.vertices.shape[0]} frames "
        f"({motion.duration_s:.2f} s at {anim.fps:g} fps), {anim.vertices.shape[1]} vertices on body "
        f"{anim.body_name}{cloth}; mode {named}{gate}, {used}; {seconds:.1f} s"
    )
    if anim.penetration is not None:
        p = anim.penetration
        print(
            f"  penetration (vertices > 5 mm inside the body): before push-out {100 * p.inside_before:.2f} % "
            f"(worst frame {100 * p.worst_before:.2f} %), after {100 * p.inside_after:.2f} % "
            f"(worst {100 * p.worst_after:.2f} %); the strain limit repaired the push on "
            f"{100 * p.limited:.1f} % of frames"
        )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-animate``; returns the exit status."""
    return run_cli(_main, argv, "hrr-animate")


if __name__ == "__main__":
    sys.exit(main())
